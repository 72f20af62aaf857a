//! Checks of a mesh before it enters a scene: finite positions and transform, ordered valid
//! materials, vertex colours in [0, 1]; each error names the scene, the mesh and the place.

use super::Mesh;
use crate::error::{Error, Result};
use glam::{Affine3A, Vec3};

pub(super) fn check_positions(name: &str, m: usize, mesh: &Mesh, positions: &[Vec3]) -> Result<()> {
    match positions.iter().position(|p| !p.is_finite()) {
        Some(i) => Err(Error::parse(
            name,
            format!("mesh {m} ({}), vertex {i}", mesh.name),
            format!("non-finite coordinate {:?}", positions[i]),
        )),
        None => Ok(()),
    }
}

pub(super) fn check_transform(name: &str, m: usize, mesh: &Mesh, t: &Affine3A) -> Result<()> {
    if transform_is_finite(t) {
        Ok(())
    } else {
        Err(Error::parse(
            name,
            format!("mesh {m} ({})", mesh.name),
            "non-finite transform",
        ))
    }
}

pub(super) fn check_materials(name: &str, m: usize, mesh: &Mesh) -> Result<()> {
    let nt = mesh.indices.len();
    let mut prev: Option<u32> = None;
    for (r, (first, material)) in mesh.materials.iter().enumerate() {
        let place = format!("mesh {m} ({}), material {r}", mesh.name);
        if *first as usize >= nt.max(1) || prev.is_some_and(|p| p >= *first) {
            return Err(Error::parse(
                name,
                place,
                format!("first triangle {first} out of order or past the mesh's {nt} triangles"),
            ));
        }
        material
            .validate()
            .map_err(|e| Error::parse(name, &place, e))?;
        prev = Some(*first);
    }
    Ok(())
}

pub(super) fn check_colors(name: &str, m: usize, mesh: &Mesh) -> Result<()> {
    let place = || format!("mesh {m} ({}), vertex colours", mesh.name);
    let (nc, nv) = (mesh.colors.len(), mesh.positions.len());
    if nc != 0 && nc != nv {
        return Err(Error::parse(
            name,
            place(),
            format!("{nc} colours for {nv} vertices"),
        ));
    }
    if let Some(i) = mesh
        .colors
        .iter()
        .position(|c| !(c.is_finite() && c.min_element() >= 0.0 && c.max_element() <= 1.0))
    {
        return Err(Error::parse(
            name,
            place(),
            format!(
                "vertex {i}: colour {:?} is not in [0, 1]",
                mesh.colors[i].to_array()
            ),
        ));
    }
    Ok(())
}

fn transform_is_finite(t: &Affine3A) -> bool {
    t.matrix3.x_axis.is_finite()
        && t.matrix3.y_axis.is_finite()
        && t.matrix3.z_axis.is_finite()
        && t.translation.is_finite()
}
