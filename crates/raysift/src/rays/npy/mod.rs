//! The numpy file formats (README, "Formats"):
//!
//! - `rays.npy`: float32, shape `(N, 6)` `[ox, oy, oz, dx, dy, dz]` (then `tmin = 0`, `tmax = +inf`)
//!   or `(N, 8)` `[..., tmin, tmax]`, C order, either byte order; float64 (numpy's default) is
//!   converted to float32 once, on reading ([`read_rays`]). Origins and directions must be
//!   finite, directions non-zero, `tmin` not NaN. Camera rays may also be image-shaped,
//!   `(H, W, 6)` or `(H, W, 8)` (pixel `(i, j)` at row `j`, column `i`); [`write_rays`] writes
//!   pinhole batches that way so the image size survives the file. [`read_rays`] recovers the
//!   layout hint ([`RayBatch::detect_layout`]): pinhole for image-shaped rays from one point,
//!   to-a-point for shadow segments.
//! - `hits.npy`: a structured array of N records `t <f4` (+inf on miss), `prim <u4`
//!   (4294967295 on miss), `geom <u4` (the mesh holding `prim`, 4294967295 on miss), `u <f4`,
//!   `v <f4`, and with normals asked for `ng <f4 (3,)` (the unit geometric normal, zeros on
//!   miss) ([`write_hits`]). [`read_hits`] reads these and the older files without `geom`.
//! - occlusion: `uint8` array of N (1 = occluded).

use super::{HitBatch, Ray, RayBatch, RayLayout};
use crate::error::{Error, Result};
use crate::output::write_atomic;
use crate::scene::Scene;
use npyz::WriterBuilder;
use std::io::Read;
use std::path::Path;

/// One record of a `hits.npy` without the mesh id (as raysift wrote them before `geom`, and as
/// other programs may still write them): read by [`read_hits`], never written.
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

/// One record of `hits.npy` as [`write_hits`] writes it: the hit and the mesh it is on.
#[derive(
    npyz::Serialize, npyz::Deserialize, npyz::AutoSerialize, Clone, Copy, Debug, PartialEq,
)]
pub struct GeomHitRecord {
    /// Hit distance.
    pub t: f32,
    /// Triangle id.
    pub prim: u32,
    /// Mesh (geometry) id of the triangle ([`Scene::geometry_of`]).
    pub geom: u32,
    /// Barycentric u.
    pub u: f32,
    /// Barycentric v.
    pub v: f32,
}

/// One record of `hits.npy` with the geometric normal (`write_hits(.., normals: true)`).
#[derive(
    npyz::Serialize, npyz::Deserialize, npyz::AutoSerialize, Clone, Copy, Debug, PartialEq,
)]
pub struct NormalHitRecord {
    /// Hit distance.
    pub t: f32,
    /// Triangle id.
    pub prim: u32,
    /// Mesh (geometry) id of the triangle.
    pub geom: u32,
    /// Barycentric u.
    pub u: f32,
    /// Barycentric v.
    pub v: f32,
    /// Unit geometric normal of the triangle in world space ([`Scene::normal`]; zeros on miss).
    pub ng: [f32; 3],
}

/// The longest `.npy` header (its Python dict literal) accepted, in bytes: numpy.load's own
/// default `max_header_size`. raysift's files have headers of about 120 bytes.
pub const MAX_HEADER: usize = 10_000;

/// The deepest bracket nesting accepted in a header: a structured dtype with a subarray field
/// needs 4 (`{[((`), raysift's own files 3. npyz's header parser (py_literal, on pest)
/// backtracks exponentially on nested brackets: a 10 KB header of `{}` nested 5 deep takes
/// 0.4 s, 8 deep 6 s, 10 deep 42 s.
pub const MAX_HEADER_NESTING: usize = 4;

/// An opened `.npy` input: npyz's reader positioned at the data, and the number of data bytes
/// after the header.
pub(crate) struct Opened<R: Read> {
    pub(crate) npy: npyz::NpyFile<std::io::Chain<std::io::Cursor<Vec<u8>>, R>>,
    pub(crate) data_len: u64,
}

pub(crate) fn open_file(path: &Path) -> Result<(std::io::BufReader<std::fs::File>, u64)> {
    let name = path.display().to_string();
    let f = std::fs::File::open(path).map_err(|e| Error::io(&name, e))?;
    let len = f.metadata().map_err(|e| Error::io(&name, e))?.len();
    Ok((std::io::BufReader::new(f), len))
}

/// Reads the fixed part and the header text of a `.npy` stream of `total_len` bytes and checks
/// them before npyz sees them: npyz allocates the header length the file declares (up to
/// 4 GiB), multiplies the shape unchecked (an overflow panic with overflow checks on) and
/// parses the header with exponential backtracking on nested brackets. Then hands npyz the
/// same bytes.
pub(crate) fn open_npy<R: Read>(mut r: R, total_len: u64, name: &str) -> Result<Opened<R>> {
    let err = |msg: String| Error::parse(name, "header", msg);
    let mut pre = vec![0u8; 8];
    r.read_exact(&mut pre)
        .map_err(|_| err("not a valid .npy file (shorter than its 8-byte magic)".into()))?;
    if &pre[..6] != b"\x93NUMPY" {
        return Err(err(
            "not a valid .npy file (it does not start with \\x93NUMPY)".into(),
        ));
    }
    let len_bytes = match (pre[6], pre[7]) {
        (1, 0) => 2,
        (2, 0) | (3, 0) => 4,
        (a, b) => {
            return Err(err(format!(
                "not a valid .npy file (unsupported format version {a}.{b})"
            )))
        }
    };
    let mut lb = [0u8; 4];
    r.read_exact(&mut lb[..len_bytes])
        .map_err(|_| err("not a valid .npy file (truncated before the header length)".into()))?;
    pre.extend_from_slice(&lb[..len_bytes]);
    let header_len = u32::from_le_bytes(lb) as usize;
    if header_len > MAX_HEADER {
        return Err(err(format!(
            "the file declares a header of {header_len} bytes; at most {MAX_HEADER} are accepted (numpy.load's default max_header_size)"
        )));
    }
    let start = pre.len() as u64 + header_len as u64;
    if start > total_len {
        return Err(err(format!(
            "the file declares a header of {header_len} bytes but has only {} after the first {}",
            total_len - pre.len() as u64,
            pre.len()
        )));
    }
    let mut text = vec![0u8; header_len];
    r.read_exact(&mut text)
        .map_err(|e| err(format!("cannot read the {header_len}-byte header: {e}")))?;
    precheck_header(&text).map_err(err)?;
    pre.extend_from_slice(&text);
    let npy = npyz::NpyFile::new(std::io::Cursor::new(pre).chain(r))
        .map_err(|e| err(format!("not a valid .npy file ({e})")))?;
    Ok(Opened {
        npy,
        data_len: total_len - start,
    })
}

/// Bounds what npyz would otherwise panic or stall on, with a small scan of the header text
/// (Python literal; strings skipped): bracket nesting at most [`MAX_HEADER_NESTING`], every
/// integer literal at most `u64::MAX`, and the product of all integer literals (each counted as
/// at least 2) at most `u64::MAX`. The last bounds every partial product of the shape whatever
/// `+`/`-` expressions its dimensions are written as, so npyz's unchecked shape and stride
/// products cannot overflow; real headers (a shape and a dtype) are far below it.
fn precheck_header(text: &[u8]) -> std::result::Result<(), String> {
    let mut depth = 0usize;
    let mut bound: u128 = 1;
    let mut i = 0;
    let ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    while i < text.len() {
        let c = text[i];
        match c {
            b'\'' | b'"' => {
                let q = if text[i..].starts_with(&[c, c, c]) {
                    3
                } else {
                    1
                };
                i += q;
                while i < text.len() {
                    if text[i] == b'\\' {
                        i += 2;
                    } else if text[i] == c && text[i..].starts_with(&[c, c, c][..q]) {
                        i += q;
                        break;
                    } else {
                        i += 1;
                    }
                }
            }
            b'(' | b'[' | b'{' => {
                depth += 1;
                if depth > MAX_HEADER_NESTING {
                    return Err(format!(
                        "brackets nested deeper than {MAX_HEADER_NESTING} levels in the header"
                    ));
                }
                i += 1;
            }
            b')' | b']' | b'}' => {
                depth = depth.saturating_sub(1);
                i += 1;
            }
            b'0'..=b'9' if i == 0 || !ident(text[i - 1]) => {
                let s = i;
                while i < text.len() && (ident(text[i]) || text[i] == b'.') {
                    i += 1;
                }
                let tok = &text[s..i];
                if let Some(v) = int_literal(tok) {
                    let v = v.ok_or_else(|| {
                        format!(
                            "number {} in the header is larger than 2^64",
                            String::from_utf8_lossy(&tok[..tok.len().min(40)])
                        )
                    })?;
                    bound = bound.saturating_mul(v.max(2) as u128);
                    if bound > u64::MAX as u128 {
                        return Err(
                            "the shape's dimensions multiply past 2^64 (no file holds that many elements)"
                                .into(),
                        );
                    }
                }
            }
            _ => i += 1,
        }
    }
    Ok(())
}

/// A Python integer literal (`12`, `1_000`, `0x1F`, `0o7`, `0b1`): `Some(Some(v))`,
/// `Some(None)` when it exceeds `u64::MAX`, `None` when `tok` is not an integer (a float).
fn int_literal(tok: &[u8]) -> Option<Option<u64>> {
    let (radix, digits) = match tok {
        [b'0', b'x' | b'X', rest @ ..] => (16, rest),
        [b'0', b'o' | b'O', rest @ ..] => (8, rest),
        [b'0', b'b' | b'B', rest @ ..] => (2, rest),
        _ => (10, tok),
    };
    let mut v: u64 = 0;
    let mut any = false;
    let mut overflow = false;
    for &d in digits {
        if d == b'_' {
            continue;
        }
        let x = (d as char).to_digit(radix)?;
        any = true;
        match v
            .checked_mul(radix as u64)
            .and_then(|v| v.checked_add(x as u64))
        {
            Some(n) => v = n,
            None => overflow = true,
        }
    }
    if !any {
        return None;
    }
    Some((!overflow).then_some(v))
}

/// Checks that the data after the header is exactly `count` items of `item` bytes (what the
/// header's shape declares), and that `mem_each` bytes per item fit in memory, before anything
/// is read or reserved.
pub(crate) fn check_sizes<R: Read>(
    o: &Opened<R>,
    name: &str,
    count: u64,
    item: u64,
    what: &str,
    mem_each: u64,
) -> Result<()> {
    let shape = o.npy.shape();
    let need = count
        .checked_mul(item)
        .ok_or_else(|| Error::parse(name, "header", format!("shape {shape:?} too large")))?;
    if need > o.data_len {
        return Err(Error::parse(
            name,
            "data",
            format!(
                "the header's shape {shape:?} needs {need} bytes of data but the file has {} after its header (truncated, or a wrong shape)",
                o.data_len
            ),
        ));
    }
    if need < o.data_len {
        return Err(Error::parse(
            name,
            "data",
            format!(
                "{} bytes after the {need} bytes of data the header's shape {shape:?} declares (wrong shape?)",
                o.data_len - need
            ),
        ));
    }
    crate::scene::io::limits::check_memory(
        name,
        "header",
        &format!("the {count} {what} ({mem_each} bytes each in memory)"),
        count.saturating_mul(mem_each),
    )
}

pub(crate) fn is_plain(dtype: &npyz::DType, kind: char, size: u64) -> bool {
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
    let (f, len) = open_file(path)?;
    rays_from(open_npy(f, len, &name)?, &name)
}

/// Parses and validates the bytes of a rays file ([`read_rays`] without the file system);
/// `name` names the input in errors. The fuzz targets use it (`fuzz/`).
pub fn parse_rays(bytes: &[u8], name: &str) -> Result<RayBatch> {
    rays_from(open_npy(bytes, bytes.len() as u64, name)?, name)
}

fn rays_from<R: Read>(o: Opened<R>, name: &str) -> Result<RayBatch> {
    let name = name.to_string();
    let npy = &o.npy;
    let shape = npy.shape().to_vec();
    let float64 = is_plain(&npy.dtype(), 'f', 8);
    if !float64 && !is_plain(&npy.dtype(), 'f', 4) {
        return Err(Error::parse(
            &name,
            "header",
            format!(
                "dtype is {}, expected float32 ('<f4') or float64 ('<f8')",
                npy.dtype().descr()
            ),
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
        .try_fold(1u64, |a, &x| a.checked_mul(x))
        .filter(|&n| usize::try_from(n).is_ok())
        .ok_or_else(|| Error::parse(&name, "header", format!("shape {shape:?} too large")))?;
    let w = cols as usize;
    let item = if float64 { 8 } else { 4 };
    // 32 bytes per ray in a RayBatch, whatever the file's 6 or 8 columns.
    check_sizes(&o, &name, n, item * cols, "rays", 32)?;
    let n = n as usize;
    // Where a bad value is: the row, or the pixel of an image-shaped array.
    let place = |i: usize| match image {
        Some((iw, _)) => format!("pixel [{}, {}]", i / iw as usize, i % iw as usize),
        None => format!("row {i}"),
    };
    // Streamed row by row into the batch: the file's values are never held twice. float64
    // files are converted once, value by value (round to nearest: raysift traces in float32, as
    // Embree does); a finite value beyond float32's range is an error, since it would become
    // infinite.
    let header_err = |e: npyz::DTypeError| Error::parse(&name, "header", e.to_string());
    let mut values: Box<dyn Iterator<Item = std::io::Result<f64>>> = if float64 {
        Box::new(o.npy.data::<f64>().map_err(header_err)?)
    } else {
        Box::new(
            o.npy
                .data::<f32>()
                .map_err(header_err)?
                .map(|r| r.map(f64::from)),
        )
    };
    let mut rays = RayBatch::with_capacity(n);
    let mut row = [0f32; 8];
    for i in 0..n {
        for x in row.iter_mut().take(w) {
            *x = match values.next() {
                Some(Ok(v)) if v.is_finite() && !(v as f32).is_finite() => {
                    return Err(Error::parse(
                        &name,
                        place(i),
                        format!("value {v:e} is beyond float32's range"),
                    ))
                }
                Some(Ok(v)) => v as f32,
                Some(Err(e)) => {
                    return Err(Error::parse(&name, place(i), format!("read error: {e}")))
                }
                None => return Err(Error::parse(&name, place(i), "unexpected end of data")),
            };
        }
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

/// Writes `scene`'s world-space triangles as float32 `(T, 9)`, corners in primitive-id order
/// (`raysift export`, and the Embree peer's input).
pub fn write_triangles(path: impl AsRef<Path>, scene: &Scene) -> Result<()> {
    let t = scene.triangles();
    write_atomic(path.as_ref(), |w| {
        let mut o = npyz::WriteOptions::<f32>::new()
            .default_dtype()
            .shape(&[t.len() as u64, 9])
            .writer(w)
            .begin_nd()?;
        for i in 0..t.len() {
            for v in t.get(i) {
                o.extend(v.to_array())?;
            }
        }
        o.finish()
    })
}

/// Writes closest hits as the structured `hits.npy`: `t prim geom u v` per ray, and `ng` (the
/// unit geometric normal) when `normals` is set. `scene` is the scene the hits are of (for the
/// mesh ids and normals).
pub fn write_hits(
    path: impl AsRef<Path>,
    hits: &HitBatch,
    scene: &Scene,
    normals: bool,
) -> Result<()> {
    let geom = |i: usize| scene.geometry_of(hits.prim[i]);
    if normals {
        write_records(path.as_ref(), hits.len(), |i| NormalHitRecord {
            t: hits.t[i],
            prim: hits.prim[i],
            geom: geom(i),
            u: hits.u[i],
            v: hits.v[i],
            ng: if hits.is_hit(i) {
                scene.normal(hits.prim[i] as usize).to_array()
            } else {
                [0.0; 3]
            },
        })
    } else {
        write_records(path.as_ref(), hits.len(), |i| GeomHitRecord {
            t: hits.t[i],
            prim: hits.prim[i],
            geom: geom(i),
            u: hits.u[i],
            v: hits.v[i],
        })
    }
}

/// Writes `n` records `record(0..n)` as a 1-d structured array.
pub(crate) fn write_records<T: npyz::AutoSerialize>(
    path: &Path,
    n: usize,
    record: impl Fn(usize) -> T,
) -> Result<()> {
    write_atomic(path, |w| {
        let mut out = npyz::WriteOptions::<T>::new()
            .default_dtype()
            .shape(&[n as u64])
            .writer(w)
            .begin_nd()?;
        for i in 0..n {
            out.push(&record(i))?;
        }
        out.finish()
    })
}

/// Reads a `hits.npy` file: records `t prim geom u v` with or without `ng`, or the older
/// `t prim u v`. The mesh ids and normals are not kept (the scene gives them again).
pub fn read_hits(path: impl AsRef<Path>) -> Result<HitBatch> {
    let path = path.as_ref();
    let name = path.display().to_string();
    let (f, len) = open_file(path)?;
    hits_from(open_npy(f, len, &name)?, &name)
}

/// Parses the bytes of a `hits.npy` file ([`read_hits`] without the file system).
pub fn parse_hits(bytes: &[u8], name: &str) -> Result<HitBatch> {
    hits_from(open_npy(bytes, bytes.len() as u64, name)?, name)
}

fn hits_from<R: Read>(o: Opened<R>, name: &str) -> Result<HitBatch> {
    use npyz::AutoSerialize;
    let dtype = o.npy.dtype();
    if dtype == GeomHitRecord::default_dtype() {
        hit_records(o, name, 20, |r: &GeomHitRecord| (r.t, r.prim, r.u, r.v))
    } else if dtype == NormalHitRecord::default_dtype() {
        hit_records(o, name, 32, |r: &NormalHitRecord| (r.t, r.prim, r.u, r.v))
    } else if dtype == HitRecord::default_dtype() {
        hit_records(o, name, 16, |r: &HitRecord| (r.t, r.prim, r.u, r.v))
    } else {
        Err(Error::parse(
            name,
            "header",
            format!(
                "dtype is {}, expected {} (optionally with ng), or {}",
                dtype.descr(),
                GeomHitRecord::default_dtype().descr(),
                HitRecord::default_dtype().descr()
            ),
        ))
    }
}

/// The `(t, prim, u, v)` of every record of type `T` (`size` bytes each in the file), streamed.
fn hit_records<T: npyz::Deserialize, R: Read>(
    o: Opened<R>,
    name: &str,
    size: u64,
    fields: impl Fn(&T) -> (f32, u32, f32, f32),
) -> Result<HitBatch> {
    check_sizes(&o, name, o.npy.len(), size, "hits", 16)?;
    let n = o.npy.len() as usize;
    let mut h = HitBatch::new(0);
    for v in [&mut h.t, &mut h.u, &mut h.v] {
        v.reserve_exact(n);
    }
    h.prim.reserve_exact(n);
    let recs = o
        .npy
        .data::<T>()
        .map_err(|e| Error::parse(name, "header", e.to_string()))?;
    for (i, r) in recs.enumerate() {
        let r = r.map_err(|e| Error::parse(name, format!("record {i}"), e.to_string()))?;
        let (t, prim, u, v) = fields(&r);
        h.t.push(t);
        h.prim.push(prim);
        h.u.push(u);
        h.v.push(v);
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
    let (f, len) = open_file(path)?;
    occlusion_from(open_npy(f, len, &name)?, &name)
}

/// Parses the bytes of an occlusion file ([`read_occlusion`] without the file system).
pub fn parse_occlusion(bytes: &[u8], name: &str) -> Result<Vec<bool>> {
    occlusion_from(open_npy(bytes, bytes.len() as u64, name)?, name)
}

fn occlusion_from<R: Read>(o: Opened<R>, name: &str) -> Result<Vec<bool>> {
    if !is_plain(&o.npy.dtype(), 'u', 1) || o.npy.shape().len() != 1 {
        return Err(Error::parse(
            name,
            "header",
            format!(
                "expected a 1-d uint8 array, got {} {:?}",
                o.npy.dtype().descr(),
                o.npy.shape()
            ),
        ));
    }
    check_sizes(&o, name, o.npy.len(), 1, "occlusion flags", 1)?;
    let mut out = Vec::with_capacity(o.npy.len() as usize);
    let flags = o
        .npy
        .data::<u8>()
        .map_err(|e| Error::parse(name, "header", e.to_string()))?;
    for (i, b) in flags.enumerate() {
        let b = b.map_err(|e| Error::parse(name, format!("element {i}"), e.to_string()))?;
        out.push(b != 0);
    }
    Ok(out)
}

#[cfg(test)]
mod tests;
