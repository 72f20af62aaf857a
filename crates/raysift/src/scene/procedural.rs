//! Generated scenes, addressable by name from the command line:
//!
//! | spec | scene |
//! |---|---|
//! | `sphere:N` | unit icosphere with about N triangles (20·4^k, k chosen nearest to N in log scale) |
//! | `soup:N[:SEED]` | N random small triangles in the box [-1,1]³ (seed 1 by default) |
//! | `cornell` | the Cornell box: five walls, two blocks and the light, as quads fanned in two |
//! | `tile:K:FILE` | K×K×1 copies of a scene file in a grid in x and y (for multi-million-triangle scenes of real geometry) |

use super::{Mesh, Scene};
use crate::error::{Error, Result};
use glam::{Affine3A, Vec3};
use rand::{Rng, SeedableRng};
use std::collections::HashMap;

/// Opens a scene by spec: a generator (`sphere:N`, `soup:N[:SEED]`, `cornell`, `tile:K:FILE`) or a
/// file path.
pub fn open(spec: &str) -> Result<Scene> {
    let (head, rest) = spec.split_once(':').unwrap_or((spec, ""));
    match head {
        "sphere" => Ok(icosphere(parse_count(spec, rest)?)),
        "soup" => {
            let (n, seed) = rest.split_once(':').unwrap_or((rest, "1"));
            let seed = seed
                .parse::<u64>()
                .map_err(|_| Error::Invalid(format!("{spec}: seed must be a whole number")))?;
            Ok(soup(parse_count(spec, n)?, seed))
        }
        "cornell" if rest.is_empty() => Ok(cornell()),
        "tile" => {
            let (k, file) = rest
                .split_once(':')
                .ok_or_else(|| Error::Invalid(format!("{spec}: expected tile:K:FILE")))?;
            let k = parse_count(spec, k)?;
            tile(&super::load(file)?, k)
        }
        _ => super::load(spec),
    }
}

fn parse_count(spec: &str, s: &str) -> Result<usize> {
    match s.parse::<usize>() {
        Ok(n) if n > 0 => Ok(n),
        _ => Err(Error::Invalid(format!(
            "{spec}: expected a positive whole number after ':', got {s:?}"
        ))),
    }
}

/// Unit icosphere with about `n` triangles.
pub fn icosphere(n: usize) -> Scene {
    let target = (n.max(20) as f64).ln();
    let levels = (0..12).min_by(|&a, &b| {
        let da = ((20.0 * 4f64.powi(a)).ln() - target).abs();
        let db = ((20.0 * 4f64.powi(b)).ln() - target).abs();
        da.total_cmp(&db)
    });
    let levels = levels.unwrap_or(0);
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut pos: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint = |a: u32, b: u32, pos: &mut Vec<Vec3>| -> u32 {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                pos.push(((pos[a as usize] + pos[b as usize]) * 0.5).normalize());
                pos.len() as u32 - 1
            })
        };
        let mut next = Vec::with_capacity(tris.len() * 4);
        for [a, b, c] in tris {
            let ab = midpoint(a, b, &mut pos);
            let bc = midpoint(b, c, &mut pos);
            let ca = midpoint(c, a, &mut pos);
            next.extend_from_slice(&[[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    Scene::from_meshes(
        format!("sphere:{n}"),
        vec![Mesh::new("icosphere", pos, tris)],
    )
    .expect("generated sphere is valid")
}

/// `n` random triangles in [-1,1]³, each of size comparable to the mean spacing.
pub fn soup(n: usize, seed: u64) -> Scene {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
    let size = 2.0 / (n as f32).cbrt();
    let mut pos = Vec::with_capacity(3 * n);
    for _ in 0..n {
        let c = Vec3::new(
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
        );
        for _ in 0..3 {
            let o = Vec3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            );
            pos.push(c + o * size);
        }
    }
    let idx = (0..n as u32)
        .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
        .collect();
    Scene::from_meshes(
        format!("soup:{n}:{seed}"),
        vec![Mesh::new("soup", pos, idx)],
    )
    .expect("generated soup is valid")
}

/// The Cornell box (coordinates of the classic measured scene, scaled to about 2 units, y up,
/// open towards +z).
pub fn cornell() -> Scene {
    let s = 1.0 / 278.0;
    let quad = |name: &str, p: [[f32; 3]; 4]| {
        let pos = p
            .iter()
            .map(|&[x, y, z]| Vec3::new(x * s - 1.0, y * s, -z * s + 1.0))
            .collect();
        Mesh::new(name, pos, vec![[0, 1, 2], [0, 2, 3]])
    };
    let boxm = |name: &str, quads: [[[f32; 3]; 4]; 5]| {
        let mut pos = Vec::new();
        let mut idx = Vec::new();
        for q in quads {
            let b = pos.len() as u32;
            pos.extend(
                q.iter()
                    .map(|&[x, y, z]| Vec3::new(x * s - 1.0, y * s, -z * s + 1.0)),
            );
            idx.push([b, b + 1, b + 2]);
            idx.push([b, b + 2, b + 3]);
        }
        Mesh::new(name, pos, idx)
    };
    let meshes = vec![
        quad(
            "floor",
            [
                [552.8, 0.0, 0.0],
                [0.0, 0.0, 0.0],
                [0.0, 0.0, 559.2],
                [549.6, 0.0, 559.2],
            ],
        ),
        quad(
            "ceiling",
            [
                [556.0, 548.8, 0.0],
                [556.0, 548.8, 559.2],
                [0.0, 548.8, 559.2],
                [0.0, 548.8, 0.0],
            ],
        ),
        quad(
            "back",
            [
                [549.6, 0.0, 559.2],
                [0.0, 0.0, 559.2],
                [0.0, 548.8, 559.2],
                [556.0, 548.8, 559.2],
            ],
        ),
        quad(
            "right",
            [
                [0.0, 0.0, 559.2],
                [0.0, 0.0, 0.0],
                [0.0, 548.8, 0.0],
                [0.0, 548.8, 559.2],
            ],
        ),
        quad(
            "left",
            [
                [552.8, 0.0, 0.0],
                [549.6, 0.0, 559.2],
                [556.0, 548.8, 559.2],
                [556.0, 548.8, 0.0],
            ],
        ),
        quad(
            "light",
            [
                [343.0, 548.7, 227.0],
                [343.0, 548.7, 332.0],
                [213.0, 548.7, 332.0],
                [213.0, 548.7, 227.0],
            ],
        ),
        boxm(
            "short_block",
            [
                [
                    [130.0, 165.0, 65.0],
                    [82.0, 165.0, 225.0],
                    [240.0, 165.0, 272.0],
                    [290.0, 165.0, 114.0],
                ],
                [
                    [290.0, 0.0, 114.0],
                    [290.0, 165.0, 114.0],
                    [240.0, 165.0, 272.0],
                    [240.0, 0.0, 272.0],
                ],
                [
                    [130.0, 0.0, 65.0],
                    [130.0, 165.0, 65.0],
                    [290.0, 165.0, 114.0],
                    [290.0, 0.0, 114.0],
                ],
                [
                    [82.0, 0.0, 225.0],
                    [82.0, 165.0, 225.0],
                    [130.0, 165.0, 65.0],
                    [130.0, 0.0, 65.0],
                ],
                [
                    [240.0, 0.0, 272.0],
                    [240.0, 165.0, 272.0],
                    [82.0, 165.0, 225.0],
                    [82.0, 0.0, 225.0],
                ],
            ],
        ),
        boxm(
            "tall_block",
            [
                [
                    [423.0, 330.0, 247.0],
                    [265.0, 330.0, 296.0],
                    [314.0, 330.0, 456.0],
                    [472.0, 330.0, 406.0],
                ],
                [
                    [423.0, 0.0, 247.0],
                    [423.0, 330.0, 247.0],
                    [472.0, 330.0, 406.0],
                    [472.0, 0.0, 406.0],
                ],
                [
                    [472.0, 0.0, 406.0],
                    [472.0, 330.0, 406.0],
                    [314.0, 330.0, 456.0],
                    [314.0, 0.0, 456.0],
                ],
                [
                    [314.0, 0.0, 456.0],
                    [314.0, 330.0, 456.0],
                    [265.0, 330.0, 296.0],
                    [265.0, 0.0, 296.0],
                ],
                [
                    [265.0, 0.0, 296.0],
                    [265.0, 330.0, 296.0],
                    [423.0, 330.0, 247.0],
                    [423.0, 0.0, 247.0],
                ],
            ],
        ),
    ];
    Scene::from_meshes("cornell", meshes).expect("generated Cornell box is valid")
}

/// `k × k` copies of `base` in a grid in x and y (spacing 1.1 × the base's extent), one mesh per
/// copy and source mesh, each with its own translation.
pub fn tile(base: &Scene, k: usize) -> Result<Scene> {
    let b = base.bounds();
    if b.is_empty() {
        return Err(Error::Invalid(format!(
            "tile: {} has no triangles",
            base.name
        )));
    }
    let step = b.extent() * 1.1;
    let mut meshes = Vec::with_capacity(k * k * base.meshes().len());
    for j in 0..k {
        for i in 0..k {
            let offset =
                Affine3A::from_translation(Vec3::new(i as f32 * step.x, j as f32 * step.y, 0.0));
            for m in base.meshes() {
                let mut copy = m.clone();
                copy.name = format!("{}[{i},{j}]", m.name);
                copy.transform = offset * m.transform;
                meshes.push(copy);
            }
        }
    }
    Scene::from_meshes(format!("tile:{k}:{}", base.name), meshes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generators_have_expected_sizes() {
        assert_eq!(icosphere(1000).len(), 1280);
        assert_eq!(icosphere(100_000).len(), 81920);
        let s = soup(500, 3);
        assert_eq!(s.len(), 500);
        assert!(s.bounds().min.cmpge(Vec3::splat(-2.0)).all());
        assert_eq!(cornell().len(), 32);
        let t = tile(&cornell(), 3).unwrap();
        assert_eq!(t.len(), 9 * 32);
        assert!(t.bounds().extent().x > 3.0 * cornell().bounds().extent().x);
    }

    #[test]
    fn specs() {
        assert_eq!(open("sphere:80").unwrap().len(), 80);
        assert_eq!(open("soup:10:7").unwrap().len(), 10);
        assert!(open("sphere:abc")
            .unwrap_err()
            .to_string()
            .contains("sphere:abc"));
        assert!(open("soup:0").is_err());
        assert!(open("nosuch.xyz")
            .unwrap_err()
            .to_string()
            .contains("unknown scene format"));
    }
}
