//! Tests of the numpy formats (readers, writers, limits).

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
    let scene = crate::scene::procedural::open("cornell").unwrap();
    write_hits(&p, &hits, &scene, false).unwrap();
    assert_eq!(read_hits(&p).unwrap(), hits);
    write_hits(&p, &hits, &scene, true).unwrap();
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
fn hits_say_which_mesh_and_normal() {
    let dir = tempfile::tempdir().unwrap();
    let scene = crate::scene::procedural::open("cornell").unwrap();
    assert!(scene.meshes().len() > 1);
    let last = scene.len() as u32 - 1;
    let mut hits = HitBatch::new(3);
    for (i, prim) in [(0, 0), (2, last)] {
        hits.t[i] = 1.0;
        hits.prim[i] = prim;
    }
    let p = dir.path().join("h.npy");
    write_hits(&p, &hits, &scene, true).unwrap();
    let recs: Vec<NormalHitRecord> = npyz::NpyFile::new(std::fs::File::open(&p).unwrap())
        .unwrap()
        .into_vec()
        .unwrap();
    assert_eq!(recs[0].geom, 0);
    assert_eq!(recs[1].geom, u32::MAX, "a miss has no mesh");
    assert_eq!(recs[2].geom as usize, scene.meshes().len() - 1);
    assert_eq!(recs[1].ng, [0.0; 3]);
    assert_eq!(recs[2].ng, scene.normal(last as usize).to_array());
    // Without normals the record has no ng; files of the older layout still read.
    write_hits(&p, &hits, &scene, false).unwrap();
    let header = std::fs::read(&p).unwrap();
    let text = String::from_utf8_lossy(&header[..128]);
    assert!(text.contains("'geom'") && !text.contains("'ng'"), "{text}");
    let mut w = npyz::WriteOptions::<HitRecord>::new()
        .default_dtype()
        .shape(&[3])
        .writer(std::fs::File::create(&p).unwrap())
        .begin_nd()
        .unwrap();
    for i in 0..3 {
        w.push(&HitRecord {
            t: hits.t[i],
            prim: hits.prim[i],
            u: hits.u[i],
            v: hits.v[i],
        })
        .unwrap();
    }
    w.finish().unwrap();
    assert_eq!(read_hits(&p).unwrap(), hits);
}

#[test]
fn float64_rays_are_converted_once() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("r64.npy");
    let rows: [[f64; 8]; 2] = [
        [0.1, 0.2, 3.0, 0.0, 0.0, -1.0, 0.0, f64::INFINITY],
        [1.0, 1.0 / 3.0, 2.0, 0.5, 0.25, -1.0, 0.001, 7.5],
    ];
    let mut w = npyz::WriteOptions::<f64>::new()
        .default_dtype()
        .shape(&[2, 8])
        .writer(std::fs::File::create(&p).unwrap())
        .begin_nd()
        .unwrap();
    w.extend(rows.iter().flatten().copied()).unwrap();
    w.finish().unwrap();
    let r = read_rays(&p).unwrap();
    assert_eq!(r.len(), 2);
    assert_eq!(r.oy[1], (1.0f64 / 3.0) as f32);
    assert_eq!(r.tmin[1], 0.001f64 as f32);
    assert_eq!(r.tmax[0], f32::INFINITY);
    // A finite value float32 cannot hold is refused, with its ray.
    let mut w = npyz::WriteOptions::<f64>::new()
        .default_dtype()
        .shape(&[2, 6])
        .writer(std::fs::File::create(&p).unwrap())
        .begin_nd()
        .unwrap();
    w.extend([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1e300, 0.0, 0.0, 1.0, 0.0, 0.0])
        .unwrap();
    w.finish().unwrap();
    let e = read_rays(&p).unwrap_err().to_string();
    assert!(
        e.contains("row 1") && e.contains("1e300") && e.contains("float32"),
        "{e}"
    );
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
    // Same rays as a flat (N, 8) array: recognised from the rays alone.
    let mut flat = rays.clone();
    flat.layout = RayLayout::Unknown;
    assert_eq!(flat.detect_layout(None), rays.layout);
    // One ray from elsewhere: not a pinhole batch.
    let mut moved = rays.clone();
    moved.ox[100] += 1e-3;
    assert_eq!(moved.detect_layout(Some((24, 16))), RayLayout::Unknown);

    // Shadow rays towards a light, written flat, come back as rays to that point.
    let scene = crate::scene::procedural::open("sphere:500").unwrap();
    let mut hits = HitBatch::new(rays.len());
    let mut tr = crate::tracers::create("naive", &[]).unwrap();
    tr.prepare(&scene).unwrap();
    tr.intersect(&scene, &rays, &mut hits, None).unwrap();
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
    // Wrong dtype (float64 is converted; integers are not rays).
    npyz::WriteOptions::<i32>::new()
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
