//! glTF animation playback: hand-computed poses of a small rig (`testkit::gltf_rig`: a quad
//! skinned to two joints, a rigid triangle, STEP / LINEAR / CUBICSPLINE channels), bad input,
//! and the BrainStem sample (rest pose vs the loader, per-frame changes, every tracer == naive).

use glam::{Vec3, Vec3A};
use raysift::rays::{Ray, RayBatch};
use raysift::scene::animate::playback::Playback;
use raysift::scene::io::gltf_anim::{load_animated, parse_animated};
use raysift::scene::{Change, Scene};
use raysift::testkit::gltf_rig::{at, Rig};

fn open(rig: &Rig) -> raysift::Result<(Scene, Option<Playback>)> {
    parse_animated(&rig.glb(), "rig.glb", None)
}

fn rig() -> (Scene, Playback) {
    let (s, p) = open(&Rig::new()).expect("the rig loads");
    (s, p.expect("the rig has an animation"))
}

/// World positions of mesh `m`'s vertices.
fn world(scene: &Scene, m: usize) -> Vec<Vec3> {
    let mesh = &scene.meshes()[m];
    mesh.positions
        .iter()
        .map(|&p| mesh.transform.transform_point3(p))
        .collect()
}

fn close(got: &[Vec3], want: &[Vec3]) {
    assert_eq!(got.len(), want.len());
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert!((*g - *w).length() < 1e-5, "vertex {i}: {g} != {w}");
    }
}

#[test]
fn rig_poses_equal_hand_computed_positions() {
    let (mut scene, mut p) = rig();
    assert_eq!(p.clip().name, "wave");
    assert_eq!(p.clip().duration, 2.0);
    // The loader's bind pose: the quad at its node's translation (100, 0, 0).
    assert_eq!(world(&scene, 0)[0], Vec3::new(99.5, 0.0, 0.0));

    // t = 0: every channel at its first key = the rest pose; skinning ignores the node's
    // translation, so the quad is at its bind positions.
    p.apply(&mut scene, 0.0).unwrap();
    let quad0 = [
        Vec3::new(-0.5, 0.0, 0.0),
        Vec3::new(0.5, 0.0, 0.0),
        Vec3::new(0.5, 2.0, 0.0),
        Vec3::new(-0.5, 2.0, 0.0),
    ];
    close(&world(&scene, 0), &quad0);
    close(
        &world(&scene, 1),
        &[Vec3::new(5.0, 0.0, 0.0), Vec3::new(6.0, 0.0, 0.0), Vec3::new(5.0, 1.0, 0.0)],
    );

    // t = 1. root: CUBICSPLINE, td = 2, s = 0.5: 0.5·0 + 2·0.125·(1,0,0) + 0.5·(2,0,0) - 0 =
    // (1.25, 0, 0). tip: slerp to 45° about z. J0 = T(1.25,0,0); J1 = T(1.25,1,0)·R45·T(0,-1,0).
    let t = p.clip().duration / 2.0;
    let before = scene.stamp();
    p.apply(&mut scene, t).unwrap();
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let j1 = |v: Vec3| {
        let (x, y) = (v.x, v.y - 1.0);
        Vec3::new(1.25 + h * x - h * y, 1.0 + h * x + h * y, v.z)
    };
    let j0 = |v: Vec3| v + Vec3::new(1.25, 0.0, 0.0);
    let top = |v: Vec3| 0.25 * j0(v) + 0.75 * j1(v);
    close(
        &world(&scene, 0),
        &[j0(quad0[0]), j0(quad0[1]), top(quad0[2]), top(quad0[3])],
    );
    assert!((top(quad0[2]) - Vec3::new(1.109835, 2.045495, 0.0)).length() < 1e-5);
    // STEP: at t = 1 the second key (90° about z) holds: T(5,0,0)·Rz90.
    close(
        &world(&scene, 1),
        &[Vec3::new(5.0, 0.0, 0.0), Vec3::new(5.0, 1.0, 0.0), Vec3::new(4.0, 0.0, 0.0)],
    );
    assert_eq!(
        scene.changes_since(before),
        Change::Meshes {
            moved: vec![1],
            deformed: vec![0]
        }
    );

    // Just before t = 1 the STEP key is still the first: the triangle is back at rest.
    p.apply(&mut scene, 0.999).unwrap();
    assert_eq!(world(&scene, 1)[1], Vec3::new(6.0, 0.0, 0.0));

    // Past the last key every channel clamps: the pose at 5 s is the pose at 2 s, and from
    // 1.5 s to 1.6 s the triangle (STEP, held) does not move while the quad deforms.
    p.apply(&mut scene, 1.5).unwrap();
    let s15 = scene.stamp();
    p.apply(&mut scene, 1.6).unwrap();
    assert_eq!(
        scene.changes_since(s15),
        Change::Meshes {
            moved: vec![],
            deformed: vec![0]
        }
    );
    p.apply(&mut scene, 2.0).unwrap();
    let at2 = world(&scene, 0);
    let s2 = scene.stamp();
    p.apply(&mut scene, 5.0).unwrap();
    assert_eq!(world(&scene, 0), at2);
    assert_eq!(scene.changes_since(s2), Change::None, "nothing changed: nothing reported");
    // t = 2: root at (2,0,0), tip rotated 90°: top vertex (0.5,2,0) -> J1 = T(2,1,0)·R90·T(0,-1,0).
    let top2 = 0.25 * (quad0[2] + Vec3::new(2.0, 0.0, 0.0)) + 0.75 * Vec3::new(2.0 - 1.0, 1.0 + 0.5, 0.0);
    assert!((at2[2] - top2).length() < 1e-5, "{} != {top2}", at2[2]);
}

#[test]
fn linear_translation_and_step_rotation_channels() {
    // Turn the root's CUBICSPLINE into LINEAR over the values (0,0,0) and (2,0,0): the output
    // is then the accessor's first two elements, so rewrite them.
    let mut r = Rig::new();
    r.json["animations"][0]["samplers"][0]["interpolation"] = "LINEAR".into();
    r.json["accessors"][10]["count"] = 2.into();
    r.set_f32(at::CUBIC, 0.0);
    r.set_f32(at::CUBIC + 12, 2.0);
    let (mut scene, p) = open(&r).unwrap();
    let mut p = p.unwrap();
    p.apply(&mut scene, 0.5).unwrap();
    // Root at (0.5, 0, 0): the bottom vertices follow it alone.
    close(&world(&scene, 0)[..2], &[Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0)]);
    // STEP rotation of the triangle switches exactly at its second key.
    p.apply(&mut scene, 1.0).unwrap();
    close(&world(&scene, 1)[1..2], &[Vec3::new(5.0, 1.0, 0.0)]);
}

fn fails(r: &Rig, field: &str, what: &str) {
    let e = open(r).err().expect("refused").to_string();
    assert!(e.starts_with("rig.glb: "), "{e}");
    assert!(e.contains(field), "{e:?} should name {field:?}");
    assert!(e.contains(what), "{e:?} should say {what:?}");
    assert!(!e.contains('\n'), "{e}");
}

#[test]
fn bad_animations_are_clear_errors() {
    let mut r = Rig::new();
    r.json["animations"][0]["channels"] = serde_json::json!([]);
    fails(&r, "animations[0].channels", "no channels");

    let mut r = Rig::new();
    r.json["accessors"][6]["count"] = 0.into();
    fails(&r, "animations[0].samplers[0].input", "no keyframes");

    let mut r = Rig::new();
    r.json["animations"][0]["channels"][1]["target"]["node"] = 9.into();
    fails(&r, "animations[0].channels[1].target.node", "refers to node 9 but there are 4 nodes");

    let mut r = Rig::new();
    r.json["accessors"][8]["count"] = 1.into();
    fails(&r, "animations[0].samplers[1].output", "1 values, 2 expected");

    let mut r = Rig::new();
    r.json["accessors"][10]["count"] = 5.into();
    fails(&r, "animations[0].samplers[0].output", "5 values, 6 expected");

    let mut r = Rig::new();
    r.set_f32(at::CUBIC + 12 + 4, f32::NAN);
    fails(&r, "animations[0].samplers[0].output (accessors[10], element 1)", "non-finite");

    let mut r = Rig::new();
    r.set_f32(at::TIMES + 4, f32::NAN);
    fails(&r, "animations[0].samplers[0].input (accessors[6], element 1)", "not finite");

    let mut r = Rig::new();
    r.set_f32(at::TIMES_STEP, 3.0);
    fails(&r, "samplers[2].input (accessors[7], element 1)", "before the previous");

    let mut r = Rig::new();
    r.set_f32(at::ROT_LINEAR + 12, 0.0);
    fails(&r, "samplers[1].output (accessors[8], element 0)", "zero length");
}

#[test]
fn bad_skins_are_clear_errors() {
    let mut r = Rig::new();
    r.json["accessors"][4]["count"] = 3.into();
    fails(&r, "meshes[0].primitives[0].attributes.WEIGHTS_0", "3 elements but POSITION has 4");

    let mut r = Rig::new();
    r.json["accessors"][3]["count"] = 5.into();
    r.json["bufferViews"][3]["byteLength"] = 40.into();
    fails(&r, "attributes.JOINTS_0", "5 elements but POSITION has 4");

    let mut r = Rig::new();
    r.json["meshes"][0]["primitives"][0]["attributes"]
        .as_object_mut()
        .unwrap()
        .remove("WEIGHTS_0");
    fails(&r, "attributes.WEIGHTS_0", "missing");

    let mut r = Rig::new();
    r.bin[at::JOINTS + 8 * 2 + 2] = 7; // vertex 2, joint slot 1 (weight 3): joint 7 of 2
    fails(&r, "attributes.JOINTS_0 (accessors[3], element 2)", "joint 7 out of range");

    let mut r = Rig::new();
    r.set_f32(at::WEIGHTS + 16, -1.0);
    fails(&r, "attributes.WEIGHTS_0 (accessors[4], element 1)", "weight -1");

    let mut r = Rig::new();
    r.set_f32(at::WEIGHTS, 0.0);
    fails(&r, "vertex 0", "sum to 0");

    let mut r = Rig::new();
    r.json["accessors"][5]["count"] = 1.into();
    fails(&r, "skins[0].inverseBindMatrices", "1 matrices for 2 joints");

    let mut r = Rig::new();
    r.set_f32(at::IBM + 64 + 52, f32::INFINITY);
    fails(&r, "skins[0].inverseBindMatrices (accessors[5], element 1)", "non-finite");
}

#[test]
fn a_file_without_animations_has_no_playback() {
    let mut r = Rig::new();
    r.json.as_object_mut().unwrap().remove("animations");
    let (scene, p) = open(&r).unwrap();
    assert!(p.is_none());
    assert_eq!(scene.meshes().len(), 2);
}

fn brainstem() -> Option<std::path::PathBuf> {
    let dir = raysift::testkit::shared_scenes("BrainStem animation")?;
    let p = dir.join("animated").join("BrainStem.glb");
    if !p.is_file() {
        eprintln!("SKIPPED: BrainStem animation: {} not found", p.display());
        return None;
    }
    Some(p)
}

#[test]
fn brainstem_rest_pose_matches_the_loader_and_frames_deform_every_mesh() {
    let Some(path) = brainstem() else { return };
    let (loaded, p) = load_animated(&path).unwrap();
    let mut p = p.expect("BrainStem has an animation");
    assert_eq!(loaded.len(), 61_666);
    assert_eq!(p.skinned().len(), 59);
    assert!(p.rigid().is_empty());
    assert!((p.clip().duration - 34.88).abs() < 1e-3, "{}", p.clip().duration);
    // The rest pose skinned (joints at their file TRS, global · inverseBind) is NOT the
    // loader's bind pose in this file (re-exported by three.js): its joint nodes' TRS are not
    // the inverses of the inverse bind matrices, so vertices move by up to ~1.2 (size 3.1;
    // measured). What must hold: the skinned figure is the same figure, of the same size and
    // where the loader puts it (a wrong joint order or matrix product scatters vertices).
    let mut rest = loaded.clone();
    p.apply_rest(&mut rest).unwrap();
    let mut f0 = loaded.clone();
    p.apply(&mut f0, 0.0).unwrap();
    let (lb, size) = (loaded.bounds(), loaded.bounds().extent().length());
    for (what, s) in [("rest pose", &rest), ("frame 0", &f0)] {
        let worst = (0..loaded.meshes().len())
            .flat_map(|m| world(&loaded, m).into_iter().zip(world(s, m)))
            .map(|(a, b)| (a - b).length())
            .fold(0f32, f32::max);
        let (b, r) = (s.bounds(), s.bounds().extent().length() / size);
        eprintln!("BrainStem {what} vs loader: worst vertex distance {worst:.3}, size ratio {r:.3}");
        assert!((0.6..1.5).contains(&r), "{what}: size ratio {r}");
        assert!((b.center() - lb.center()).length() < 0.2 * size, "{what}: {b:?} vs {lb:?}");
    }

    // Frame 0 is the clip's first keys, not the rest pose: it differs, and every skinned mesh
    // deforms from frame to frame (no mesh moves rigidly: all 59 are skinned).
    let mut s = loaded.clone();
    p.apply(&mut s, 0.0).unwrap();
    let first = s.stamp();
    p.apply(&mut s, p.clip().duration / 60.0).unwrap();
    match s.changes_since(first) {
        Change::Meshes { moved, deformed } => {
            assert!(moved.is_empty());
            assert_eq!(deformed.len(), 59, "{deformed:?}");
        }
        c => panic!("{c:?}"),
    }
    assert!(p.bytes() >= 48 * 34_159, "{}", p.bytes());
}

#[test]
fn brainstem_every_tracer_equals_naive_over_frames() {
    let Some(path) = brainstem() else { return };
    let (mut scene, p) = load_animated(&path).unwrap();
    let mut p = p.unwrap();
    p.apply(&mut scene, 0.0).unwrap();
    // Rays from around the figure towards its centre, fixed for all frames.
    let b = scene.bounds();
    let (c, r) = (b.center(), b.extent().length());
    let mut rays = RayBatch::with_capacity(4096);
    for i in 0..4096u32 {
        let a = i as f32 * 0.618_034 * std::f32::consts::TAU;
        let z = (i as f32 + 0.5) / 4096.0 * 2.0 - 1.0;
        let o = Vec3A::from(c) + Vec3A::new(a.cos(), a.sin(), z) * r;
        let d = (Vec3A::from(c) - o).normalize() + Vec3A::new(0.0, 0.0, 0.02 * z);
        rays.push(Ray {
            origin: o.into(),
            dir: d.into(),
            tmin: 0.0,
            tmax: f32::INFINITY,
        });
    }
    let d = p.clip().duration;
    raysift::testkit::check_animation(&scene, 3, |s, f| p.apply(s, f as f32 * d / 3.0).unwrap(), &rays)
        .unwrap();
}
