//! The numpy file formats (README, "Formats"):
//!
//! - `rays.npy`: float32, shape `(N, 6)` `[ox, oy, oz, dx, dy, dz]` (then `tmin = 0`, `tmax = +inf`)
//!   or `(N, 8)` `[..., tmin, tmax]`, C order, either byte order. Origins and directions must be
//!   finite, directions non-zero, `tmin` not NaN. Camera rays may also be image-shaped,
//!   `(H, W, 6)` or `(H, W, 8)` (pixel `(i, j)` at row `j`, column `i`); [`write_rays`] writes
//!   pinhole batches that way so the image size survives the file. [`read_rays`] recovers the
//!   layout hint ([`RayBatch::detect_layout`]): pinhole for image-shaped rays from one point,
//!   to-a-point for shadow segments.
//! - `hits.npy`: a structured array of N records `t <f4` (+inf on miss), `prim <u4`
//!   (4294967295 on miss), `u <f4`, `v <f4`.
//! - occlusion: `uint8` array of N (1 = occluded).

use super::{HitBatch, Ray, RayBatch, RayLayout};
use crate::error::{Error, Result};
use crate::output::write_atomic;
use npyz::WriterBuilder;
use std::io::Read;
use std::path::Path;

/// One record of `hits.npy`.
#[derive(
    npyz::Serialize, npyz::Deserialize, npyz::AutoSerialize, Clone, Copy, Debug, PartialEq,
)]
pub struct HitRecord {
    /// Hit distance.
    pub t: f32,
    /// Triangle id.
    pub prim: u32,
    /// Barycentric u.
    pub u: f32,
    /// Barycentric v.
    pub v: f32,
}

fn open_file(path: &Path) -> Result<std::io::BufReader<std::fs::File>> {
    let name = path.display().to_string();
    let f = std::fs::File::open(path).map_err(|e| Error::io(&name, e))?;
    Ok(std::io::BufReader::new(f))
}

fn open_npy<R: Read>(r: R, name: &str) -> Result<npyz::NpyFile<R>> {
    npyz::NpyFile::new(r)
        .map_err(|e| Error::parse(name, "header", format!("not a valid .npy file ({e})")))
}

fn is_plain(dtype: &npyz::DType, kind: char, size: u64) -> bool {
    match dtype {
        npyz::DType::Plain(ts) => {
            let s = ts.to_string();
            s.len() >= 3 && s[1..].starts_with(kind) && ts.size_field() == size
        }
        _ => false,
    }
}

/// Reads and validates a rays file.
pub fn read_rays(path: impl AsRef<Path>) -> Result<RayBatch> {
    let path = path.as_ref();
    let name = path.display().to_string();
    rays_from(open_npy(open_file(path)?, &name)?, &name)
}

/// Parses and validates the bytes of a rays file ([`read_rays`] without the file system);
/// `name` names the input in errors. The fuzz targets use it (`fuzz/`).
pub fn parse_rays(bytes: &[u8], name: &str) -> Result<RayBatch> {
    rays_from(open_npy(bytes, name)?, name)
}

fn rays_from<R: Read>(npy: npyz::NpyFile<R>, name: &str) -> Result<RayBatch> {
    let name = name.to_string();
    let shape = npy.shape().to_vec();
    if !is_plain(&npy.dtype(), 'f', 4) {
        return Err(Error::parse(
            &name,
            "header",
            format!("dtype is {}, expected float32 ('<f4')", npy.dtype().descr()),
        ));
    }
    let cols = shape.last().copied().unwrap_or(0);
    if !(shape.len() == 2 || shape.len() == 3) || !(cols == 6 || cols == 8) {
        return Err(Error::parse(
            &name,
            "header",
            format!("shape is {shape:?}, expected (N, 6), (N, 8), (H, W, 6) or (H, W, 8)"),
        ));
    }
    let image = match shape[..] {
        [h, w, _] if h <= u32::MAX as u64 && w <= u32::MAX as u64 => Some((w as u32, h as u32)),
        [_, _, _] => {
            return Err(Error::parse(
                &name,
                "header",
                format!("image shape {shape:?} too large"),
            ))
        }
        _ => None,
    };
    if npy.order() != npyz::Order::C {
        return Err(Error::parse(
            &name,
            "header",
            "Fortran-ordered array; save it in C order (numpy.ascontiguousarray)",
        ));
    }
    let n = shape[..shape.len() - 1]
        .iter()
        .try_fold(1usize, |a, &x| a.checked_mul(x as usize))
        .ok_or_else(|| Error::parse(&name, "header", format!("shape {shape:?} too large")))?;
    let w = cols as usize;
    let data: Vec<f32> = npy.into_vec().map_err(|e| {
        Error::parse(
            &name,
            "data",
            format!("expected {n} rows of {w} float32 values: {e}"),
        )
    })?;
    if data.len() != n * w {
        return Err(Error::parse(
            &name,
            "data",
            format!("expected {} values, found {}", n * w, data.len()),
        ));
    }
    let mut rays = RayBatch::with_capacity(n);
    // Where a bad value is: the row, or the pixel of an image-shaped array.
    let place = |i: usize| match image {
        Some((iw, _)) => format!("pixel [{}, {}]", i / iw as usize, i % iw as usize),
        None => format!("row {i}"),
    };
    for (i, row) in data.chunks_exact(w).enumerate() {
        let (tmin, tmax) = if w == 8 {
            (row[6], row[7])
        } else {
            (0.0, f32::INFINITY)
        };
        if row[..6].iter().any(|x| !x.is_finite()) {
            return Err(Error::parse(
                &name,
                place(i),
                format!("non-finite origin or direction {:?}", &row[..6]),
            ));
        }
        if row[3] == 0.0 && row[4] == 0.0 && row[5] == 0.0 {
            return Err(Error::parse(&name, place(i), "zero direction"));
        }
        if tmin.is_nan() || tmax.is_nan() {
            return Err(Error::parse(&name, place(i), "tmin or tmax is NaN"));
        }
        rays.push(Ray {
            origin: glam::Vec3::new(row[0], row[1], row[2]),
            dir: glam::Vec3::new(row[3], row[4], row[5]),
            tmin,
            tmax,
        });
    }
    rays.layout = rays.detect_layout(image);
    Ok(rays)
}

/// Writes rays as float32 `(N, 8)`, or `(H, W, 8)` for pinhole batches (so readers recover the
/// image size).
pub fn write_rays(path: impl AsRef<Path>, rays: &RayBatch) -> Result<()> {
    let n = rays.len();
    let shape = match rays.layout {
        RayLayout::Pinhole { width, height, .. } if width as usize * height as usize == n => {
            vec![height as u64, width as u64, 8]
        }
        _ => vec![n as u64, 8],
    };
    write_atomic(path.as_ref(), |w| {
        let mut out = npyz::WriteOptions::<f32>::new()
            .default_dtype()
            .shape(&shape)
            .writer(w)
            .begin_nd()?;
        for i in 0..n {
            out.extend([
                rays.ox[i],
                rays.oy[i],
                rays.oz[i],
                rays.dx[i],
                rays.dy[i],
                rays.dz[i],
                rays.tmin[i],
                rays.tmax[i],
            ])?;
        }
        out.finish()
    })
}

/// Writes closest hits as the structured `hits.npy`.
pub fn write_hits(path: impl AsRef<Path>, hits: &HitBatch) -> Result<()> {
    let n = hits.len();
    write_atomic(path.as_ref(), |w| {
        let mut out = npyz::WriteOptions::<HitRecord>::new()
            .default_dtype()
            .shape(&[n as u64])
            .writer(w)
            .begin_nd()?;
        for i in 0..n {
            out.push(&HitRecord {
                t: hits.t[i],
                prim: hits.prim[i],
                u: hits.u[i],
                v: hits.v[i],
            })?;
        }
        out.finish()
    })
}

/// Reads a `hits.npy` file.
pub fn read_hits(path: impl AsRef<Path>) -> Result<HitBatch> {
    let path = path.as_ref();
    let name = path.display().to_string();
    hits_from(open_npy(open_file(path)?, &name)?, &name)
}

/// Parses the bytes of a `hits.npy` file ([`read_hits`] without the file system).
pub fn parse_hits(bytes: &[u8], name: &str) -> Result<HitBatch> {
    hits_from(open_npy(bytes, name)?, name)
}

fn hits_from<R: Read>(npy: npyz::NpyFile<R>, name: &str) -> Result<HitBatch> {
    let expected = <HitRecord as npyz::AutoSerialize>::default_dtype();
    if npy.dtype() != expected {
        return Err(Error::parse(
            name,
            "header",
            format!(
                "dtype is {}, expected {}",
                npy.dtype().descr(),
                expected.descr()
            ),
        ));
    }
    let recs: Vec<HitRecord> = npy
        .into_vec()
        .map_err(|e| Error::parse(name, "data", e.to_string()))?;
    let mut h = HitBatch::new(0);
    for r in recs {
        h.t.push(r.t);
        h.prim.push(r.prim);
        h.u.push(r.u);
        h.v.push(r.v);
    }
    Ok(h)
}

/// Writes occlusion flags as `uint8` (1 = occluded).
pub fn write_occlusion(path: impl AsRef<Path>, occluded: &[bool]) -> Result<()> {
    write_atomic(path.as_ref(), |w| {
        let mut out = npyz::WriteOptions::<u8>::new()
            .default_dtype()
            .shape(&[occluded.len() as u64])
            .writer(w)
            .begin_nd()?;
        out.extend(occluded.iter().map(|&b| b as u8))?;
        out.finish()
    })
}

/// Reads occlusion flags written by [`write_occlusion`].
pub fn read_occlusion(path: impl AsRef<Path>) -> Result<Vec<bool>> {
    let path = path.as_ref();
    let name = path.display().to_string();
    occlusion_from(open_npy(open_file(path)?, &name)?, &name)
}

/// Parses the bytes of an occlusion file ([`read_occlusion`] without the file system).
pub fn parse_occlusion(bytes: &[u8], name: &str) -> Result<Vec<bool>> {
    occlusion_from(open_npy(bytes, name)?, name)
}

fn occlusion_from<R: Read>(npy: npyz::NpyFile<R>, name: &str) -> Result<Vec<bool>> {
    if !is_plain(&npy.dtype(), 'u', 1) || npy.shape().len() != 1 {
        return Err(Error::parse(
            name,
            "header",
            format!(
                "expected a 1-d uint8 array, got {} {:?}",
                npy.dtype().descr(),
                npy.shape()
            ),
        ));
    }
    let v: Vec<u8> = npy
        .into_vec()
        .map_err(|e| Error::parse(name, "data", e.to_string()))?;
    Ok(v.into_iter().map(|b| b != 0).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let mut rays = RayBatch::default();
        rays.push(Ray {
            origin: Vec3::new(1.0, 2.0, 3.0),
            dir: Vec3::X,
            tmin: 0.5,
            tmax: f32::INFINITY,
        });
        rays.push(Ray {
            origin: Vec3::ZERO,
            dir: -Vec3::Z,
            tmin: 0.0,
            tmax: 9.0,
        });
        let p = dir.path().join("r.npy");
        write_rays(&p, &rays).unwrap();
        let back = read_rays(&p).unwrap();
        assert_eq!(back.ox, rays.ox);
        assert_eq!(back.tmax, rays.tmax);
        let mut hits = HitBatch::new(3);
        hits.t[1] = 2.5;
        hits.prim[1] = 7;
        hits.u[1] = 0.25;
        let p = dir.path().join("h.npy");
        write_hits(&p, &hits).unwrap();
        assert_eq!(read_hits(&p).unwrap(), hits);
        let p = dir.path().join("o.npy");
        write_occlusion(&p, &[true, false, true]).unwrap();
        assert_eq!(read_occlusion(&p).unwrap(), vec![true, false, true]);
        // Empty batches are valid files.
        let p = dir.path().join("e.npy");
        write_rays(&p, &RayBatch::default()).unwrap();
        assert_eq!(read_rays(&p).unwrap().len(), 0);
    }

    #[test]
    fn layouts_survive_the_file() {
        use crate::rays::generate::shadow_rays;
        use crate::rays::Camera;
        let dir = tempfile::tempdir().unwrap();
        let cam = Camera {
            eye: Vec3::new(0.5, 1.0, 4.0),
            look: Vec3::ZERO,
            up: Vec3::Y,
            fov_deg: 40.0,
        };
        let rays = cam.rays(24, 16);
        let p = dir.path().join("cam.npy");
        write_rays(&p, &rays).unwrap();
        let back = read_rays(&p).unwrap();
        assert_eq!(back.layout, rays.layout);
        assert_eq!(back.dx, rays.dx);
        // Same rays as a flat (N, 8) array: no image size, no pinhole claim.
        let mut flat = rays.clone();
        flat.layout = RayLayout::Unknown;
        assert_eq!(flat.detect_layout(None), RayLayout::Unknown);
        // One ray from elsewhere: not a pinhole batch.
        let mut moved = rays.clone();
        moved.ox[100] += 1e-3;
        assert_eq!(moved.detect_layout(Some((24, 16))), RayLayout::Unknown);

        // Shadow rays towards a light, written flat, come back as rays to that point.
        let scene = crate::scene::procedural::open("sphere:500").unwrap();
        let mut hits = HitBatch::new(rays.len());
        let mut tr = crate::tracers::create("naive", &[]).unwrap();
        tr.prepare(std::sync::Arc::new(scene.clone())).unwrap();
        tr.intersect(&rays, &mut hits);
        let light = Vec3::new(3.0, 5.0, 2.0);
        let (sr, _) = shadow_rays(&scene, &rays, &hits, light);
        assert!(sr.len() > 10);
        let p = dir.path().join("shadow.npy");
        write_rays(&p, &sr).unwrap();
        match read_rays(&p).unwrap().layout {
            RayLayout::ToPoint { target } => assert!((target - light).length() < 1e-5),
            l => panic!("shadow rays read back as {l:?}"),
        }
        // One segment ending elsewhere, or one unbounded ray: no common end point.
        let mut off = sr.clone();
        off.dx[3] += 0.01;
        assert_eq!(off.detect_layout(None), RayLayout::Unknown);
        let mut long = sr.clone();
        long.tmax[5] = 2.0;
        assert_eq!(long.detect_layout(None), RayLayout::Unknown);
    }

    #[test]
    fn rejects_bad_files_with_place() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.npy");
        // Wrong dtype.
        npyz::WriteOptions::<f64>::new()
            .default_dtype()
            .shape(&[1, 6])
            .writer(std::fs::File::create(&p).unwrap())
            .begin_nd()
            .unwrap()
            .finish()
            .unwrap_or(());
        let e = read_rays(&p).unwrap_err().to_string();
        assert!(e.contains("bad.npy") && e.contains("dtype"), "{e}");
        // Wrong shape.
        let mut w = npyz::WriteOptions::<f32>::new()
            .default_dtype()
            .shape(&[2, 5])
            .writer(std::fs::File::create(&p).unwrap())
            .begin_nd()
            .unwrap();
        w.extend([0.0f32; 10]).unwrap();
        w.finish().unwrap();
        let e = read_rays(&p).unwrap_err().to_string();
        assert!(e.contains("shape"), "{e}");
        // NaN in row 1.
        let mut w = npyz::WriteOptions::<f32>::new()
            .default_dtype()
            .shape(&[2, 6])
            .writer(std::fs::File::create(&p).unwrap())
            .begin_nd()
            .unwrap();
        w.extend([
            0.0,
            0.0,
            0.0,
            1.0,
            0.0,
            0.0,
            0.0,
            f32::NAN,
            0.0,
            1.0,
            0.0,
            0.0,
        ])
        .unwrap();
        w.finish().unwrap();
        let e = read_rays(&p).unwrap_err().to_string();
        assert!(e.contains("row 1") && e.contains("non-finite"), "{e}");
        // Truncated data.
        let good = dir.path().join("g.npy");
        write_rays(
            &good,
            &RayBatch::from_rays(
                [Ray {
                    origin: Vec3::ZERO,
                    dir: Vec3::X,
                    tmin: 0.0,
                    tmax: 1.0,
                }; 4],
            ),
        )
        .unwrap();
        let bytes = std::fs::read(&good).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() - 10]).unwrap();
        let e = read_rays(&p).unwrap_err().to_string();
        assert!(e.contains("bad.npy") && e.contains("data"), "{e}");
        // Not an npy at all.
        std::fs::write(&p, b"hello").unwrap();
        assert!(read_rays(&p).unwrap_err().to_string().contains("header"));
    }
}
