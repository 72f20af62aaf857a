//! Cone files.
//!
//! - `cones.npy`: float32 (`'<f4'`, C order), shape `(N, 8)`, one cone per row:
//!   `[apex x, y, z, axis x, y, z, α, t_near]`, with α the **half-angle in degrees** (the
//!   paper's α, as `raysift cones --aperture`), in `(0, 90)`; the axis need not be unit
//!   (it is normalised) but must be non-zero; `t_near ≥ 0` (0: from the apex). Every value
//!   finite. An error names the file and the row.
//! - cone hits (`raysift cones --out`): a structured array of records `cone <u4`, `prim <u4`,
//!   `t <f4`, one per reported triangle, cone by cone, each cone's sorted by `(t, prim)`.

use super::{Cone, ConeBatch, ConeHits};
use crate::error::{Error, Result};
use crate::rays::npy::{check_sizes, is_plain, open_file, open_npy, write_records, Opened};
use glam::Vec3;
use std::io::Read;
use std::path::Path;

/// One record of a cone-hits file.
#[derive(
    npyz::Serialize, npyz::Deserialize, npyz::AutoSerialize, Clone, Copy, Debug, PartialEq,
)]
pub struct ConeHitRecord {
    /// Cone index (row of the cones).
    pub cone: u32,
    /// Triangle id.
    pub prim: u32,
    /// Its `t`.
    pub t: f32,
}

/// Reads and validates a `cones.npy` (module doc).
pub fn read_cones(path: impl AsRef<Path>) -> Result<ConeBatch> {
    let path = path.as_ref();
    let name = path.display().to_string();
    let (f, len) = open_file(path)?;
    cones_from(open_npy(f, len, &name)?, &name)
}

/// [`read_cones`] from bytes; `name` names the input in errors.
pub fn parse_cones(bytes: &[u8], name: &str) -> Result<ConeBatch> {
    cones_from(open_npy(bytes, bytes.len() as u64, name)?, name)
}

fn cones_from<R: Read>(o: Opened<R>, name: &str) -> Result<ConeBatch> {
    let shape = o.npy.shape().to_vec();
    if !is_plain(&o.npy.dtype(), 'f', 4) {
        return Err(Error::parse(
            name,
            "header",
            format!(
                "dtype is {}, expected float32 ('<f4')",
                o.npy.dtype().descr()
            ),
        ));
    }
    if shape.len() != 2 || shape[1] != 8 {
        return Err(Error::parse(
            name,
            "header",
            format!("shape is {shape:?}, expected (N, 8): apex xyz, axis xyz, half-angle (degrees), t_near"),
        ));
    }
    if o.npy.order() != npyz::Order::C {
        return Err(Error::parse(
            name,
            "header",
            "Fortran-ordered array; save it in C order",
        ));
    }
    let n = shape[0];
    check_sizes(&o, name, n, 32, "cones", ConeBatch::BYTES_PER_CONE as u64)?;
    let mut values = o
        .npy
        .data::<f32>()
        .map_err(|e| Error::parse(name, "header", e.to_string()))?;
    let mut b = ConeBatch::default();
    let mut row = [0f32; 8];
    for i in 0..n as usize {
        for x in row.iter_mut() {
            *x = match values.next() {
                Some(Ok(v)) => v,
                Some(Err(e)) => {
                    return Err(Error::parse(
                        name,
                        format!("row {i}"),
                        format!("read error: {e}"),
                    ))
                }
                None => {
                    return Err(Error::parse(
                        name,
                        format!("row {i}"),
                        "unexpected end of data",
                    ))
                }
            };
        }
        if row.iter().any(|x| !x.is_finite()) {
            return Err(Error::parse(
                name,
                format!("row {i}"),
                format!("non-finite value in {row:?}"),
            ));
        }
        if !(row[6] > 0.0 && row[6] < 90.0) {
            return Err(Error::parse(
                name,
                format!("row {i}"),
                format!("half-angle {}° is not in (0, 90)", row[6]),
            ));
        }
        let c = Cone {
            t_near: row[7],
            ..Cone::new(
                Vec3::new(row[0], row[1], row[2]),
                Vec3::new(row[3], row[4], row[5]),
                row[6].to_radians(),
            )
        };
        b.push(c)
            .map_err(|e| Error::parse(name, format!("row {i}"), e.to_string()))?;
    }
    Ok(b)
}

/// Writes `hits` as a cone-hits file (module doc).
pub fn write_cone_hits(path: impl AsRef<Path>, hits: &ConeHits) -> Result<()> {
    let mut cone_of = Vec::with_capacity(hits.prim.len());
    for i in 0..hits.len() {
        cone_of.extend(std::iter::repeat_n(
            i as u32,
            hits.start[i + 1] - hits.start[i],
        ));
    }
    write_records(path.as_ref(), hits.prim.len(), |k| ConeHitRecord {
        cone: cone_of[k],
        prim: hits.prim[k],
        t: hits.t[k],
    })
}

/// Reads a cone-hits file back as records.
pub fn read_cone_hits(path: impl AsRef<Path>) -> Result<Vec<ConeHitRecord>> {
    let path = path.as_ref();
    let name = path.display().to_string();
    let (f, len) = open_file(path)?;
    let o = open_npy(f, len, &name)?;
    let recs = o
        .npy
        .data::<ConeHitRecord>()
        .map_err(|e| Error::parse(&name, "header", e.to_string()))?;
    recs.enumerate()
        .map(|(i, r)| r.map_err(|e| Error::parse(&name, format!("record {i}"), e.to_string())))
        .collect()
}
