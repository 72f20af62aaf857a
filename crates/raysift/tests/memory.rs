//! Bytes per triangle and per ray, as documented in ARCHITECTURE.md and each tracer's module doc.

use raysift::scene::{procedural, Scene};
use raysift::tracers::bvh::{BvhTracer, Config};
use raysift::Tracer;
use raysift::{tracers, RayBatch};

#[test]
fn scene_soup_is_36_bytes_per_triangle_plus_its_source() {
    for s in [procedural::icosphere(20_000), procedural::soup(20_000, 1)] {
        let n = s.len();
        assert_eq!(s.triangles().bytes(), 36 * n);
        let source: usize = s
            .meshes()
            .iter()
            .map(|m| {
                12 * m.positions.capacity() + 12 * m.indices.capacity() + 12 * m.colors.capacity()
            })
            .sum();
        // Source + soup + per-mesh bookkeeping (the Mesh itself, its bounds, ranges, stamps).
        let per_mesh = std::mem::size_of::<raysift::scene::Mesh>() + 128;
        assert!(
            s.bytes() >= 36 * n + source
                && s.bytes() <= 36 * n + source + per_mesh * s.meshes().len() + 64,
            "{}",
            s.bytes()
        );
    }
    // Welded sphere: about 0.5 vertices per triangle, so about 54 B per triangle in all.
    let s = procedural::icosphere(20_000);
    let per_tri = s.bytes() as f64 / s.len() as f64;
    assert!((53.0..56.0).contains(&per_tri), "{per_tri}");
}

#[test]
fn rays_and_hits_are_32_and_16_bytes_per_ray() {
    let rays =
        raysift::rays::Camera::framing(&procedural::icosphere(80).bounds(), 45.0, 1.0).rays(64, 32);
    assert_eq!(rays.bytes(), 32 * 64 * 32);
    assert_eq!(raysift::HitBatch::new(100).bytes(), 1600);
    assert_eq!(RayBatch::default().bytes(), 0);
}

#[test]
fn naive_holds_nothing() {
    let mut t = tracers::create("naive", &[]).unwrap();
    t.prepare(&procedural::icosphere(1000)).unwrap();
    assert_eq!(t.bytes(), 0);
}

fn bvh_bytes(s: &Scene) -> (usize, usize) {
    let mut t = BvhTracer::new(Config::default()).unwrap();
    t.prepare(s).unwrap();
    (t.bvh().bytes(), t.bvh().node_count())
}

#[test]
fn bvh_is_nodes_plus_40_bytes_per_triangle() {
    for s in [
        procedural::icosphere(50_000),
        procedural::soup(50_000, 3),
        procedural::cornell(),
    ] {
        let n = s.len();
        let (bytes, nodes) = bvh_bytes(&s);
        // 32 B per node (stored in sibling pairs, plus the root's unused slot), 4 B id and 36 B
        // corner copy per triangle.
        assert!(
            bytes >= 32 * nodes + 40 * n,
            "{}: {bytes} < 32·{nodes} + 40·{n}",
            s.name
        );
        assert!(
            bytes <= 32 * (nodes + 1) + 40 * n + 64,
            "{}: {bytes} > 32·({nodes}+1) + 40·{n}",
            s.name
        );
        // A binary tree over n triangles has fewer than 2n nodes: at most 104 B per triangle.
        assert!(nodes < 2 * n.max(1));
        let mut t = tracers::create("bvh", &[]).unwrap();
        let st = t.prepare(&s).unwrap();
        assert_eq!(t.bytes(), bytes, "the tracer reports its structure's bytes");
        assert!(st.peak_bytes as usize >= bytes);
        eprintln!(
            "bvh on {}: {:.1} B per triangle ({:.2} nodes per triangle)",
            s.name,
            bytes as f64 / n as f64,
            nodes as f64 / n as f64
        );
    }
}

/// With spatial splits the same layout holds per *reference* (a triangle cut across leaves has
/// an id and a corner copy in each): 32 B per node + 40 B per reference, and at most
/// `1 + max_growth` references per triangle.
#[test]
fn bvh_spatial_is_nodes_plus_40_bytes_per_reference() {
    let big_and_small = {
        // The Cornell box's walls tiled over a dense sphere: large triangles crossing small ones.
        let cornell = procedural::cornell();
        let mut meshes = cornell.meshes().to_vec();
        meshes.extend(procedural::icosphere(20_000).meshes().iter().cloned());
        Scene::from_meshes("cornell+sphere", meshes).unwrap()
    };
    for (s, growth) in [(big_and_small, 1.0f32), (procedural::soup(20_000, 4), 0.25)] {
        let n = s.len();
        let cfg = Config {
            spatial: true,
            max_growth: growth,
            ..Config::default()
        };
        let mut t = BvhTracer::new(cfg).unwrap();
        let st = t.prepare(&s).unwrap();
        let (bytes, nodes, refs) = (t.bvh().bytes(), t.bvh().node_count(), t.bvh().ids.len());
        assert!(refs > n, "{}: no reference was cut", s.name);
        assert!(
            refs as f64 <= (1.0 + growth as f64) * n as f64,
            "{}: {refs} references",
            s.name
        );
        assert_eq!(st.built.get("references"), refs as u64);
        assert!(bytes >= 32 * nodes + 40 * refs, "{}", s.name);
        assert!(bytes <= 32 * (nodes + 1) + 40 * refs + 64, "{}", s.name);
        assert!(nodes < 2 * refs);
        eprintln!(
            "bvh spatial on {}: {:.1} B per triangle, {:.3} references per triangle",
            s.name,
            bytes as f64 / n as f64,
            refs as f64 / n as f64
        );
    }
}

/// `rtrps` holds its sphere hierarchy: per leaf a centre, radius and triangle range (24 B), per
/// inner sphere a centre, radius, leaf range and children (32 B), and the triangle ids in leaf
/// order (4 B per triangle), plus a small per-part record. With the defaults (leaves of 1
/// triangle, a binary tree of inner spheres halved down to at most 8 leaves), 50,000 leaves
/// give 8,192 bottom and 8,191 upper inner spheres: 24 + 4 + 16,383 · 32 / 50,000 = 38.5 B per
/// triangle; the 81,920-triangle icosphere 40.8.
#[test]
fn rtrps_is_about_38_to_41_bytes_per_triangle() {
    for s in [procedural::icosphere(50_000), procedural::soup(50_000, 3)] {
        let mut t = tracers::create("rtrps", &[]).unwrap();
        let st = t.prepare(&s).unwrap();
        let (n, inner) = (s.len(), st.built.get("inner") as usize);
        let want = 28 * n + 32 * inner;
        let bytes = t.bytes();
        assert!(
            (want..want + 1024).contains(&bytes),
            "{bytes} B on {} ({n} triangles, {inner} inner spheres), want {want} + the parts",
            s.name
        );
        let per = bytes as f64 / n as f64;
        assert!(
            (38.0..41.5).contains(&per),
            "{per} B per triangle on {}",
            s.name
        );
    }
}

/// Per part, `rtrps` adds its record, its index in the part tree's order (4 B) and fewer than one
/// part tree node (centre, radius, children, part range: 32 B; bottom nodes hold up to 4 parts);
/// the total is exact and stays the same after rigid updates (the tree is rebuilt in place).
#[test]
fn rtrps_parts_cost_their_record_and_under_one_tree_node() {
    use glam::{Affine3A, Vec3};
    use raysift::scene::{Mesh, Scene};
    let meshes: Vec<Mesh> = (0..300)
        .map(|k| {
            let mut m = procedural::icosphere(20 + k % 7).meshes()[0].clone();
            m.transform =
                Affine3A::from_translation(Vec3::new(k as f32 % 17.0, k as f32 / 17.0, 0.0));
            m
        })
        .collect();
    let mut scene = Scene::from_meshes("parts", meshes).unwrap();
    let mut t = tracers::create("rtrps", &[]).unwrap();
    let st = t.prepare(&scene).unwrap();
    let g = |k: &str| st.built.get(k) as usize;
    let (n, parts, inner, leaves) = (scene.len(), g("parts"), g("inner"), g("leaves"));
    let nodes = g("spheres") - parts - inner - leaves;
    assert!(
        (parts / 4..parts).contains(&nodes),
        "{nodes} part tree nodes for {parts} parts"
    );
    let part = std::mem::size_of::<raysift::accel::spheres::Part>();
    let want = 28 * n + 32 * inner + (part + 4) * parts + 32 * nodes;
    assert_eq!(t.bytes(), want);
    for f in 1..4 {
        for m in (0..300).step_by(7) {
            let xf = Affine3A::from_rotation_z(f as f32) * scene.meshes()[m].transform;
            scene.set_transform(m, xf).unwrap();
        }
        t.prepare(&scene).unwrap();
        assert_eq!(t.bytes(), want, "frame {f}");
    }
}
