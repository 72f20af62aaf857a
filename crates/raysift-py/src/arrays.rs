//! numpy inputs: array-likes to the library's types, validated, each bad value named by its
//! argument and index.
//!
//! A float32 C-contiguous array is read in place (no copy of the input); anything else (float64,
//! Fortran order, strided views, lists) is converted once by `numpy.ascontiguousarray`. Rays are
//! then transposed into the library's structure-of-arrays batch, which every tracer reads; that
//! transposition is the one copy a ray makes.

use numpy::{PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rayon::prelude::*;
use raysift::RayBatch;

/// Rays per block of the parallel transposition and validation.
const BLOCK: usize = 1 << 14;

/// A float32 C-contiguous view of `obj` (a copy only when `obj` is not already one).
pub fn f32_array<'py>(
    py: Python<'py>,
    obj: &Bound<'py, PyAny>,
    name: &str,
) -> PyResult<PyReadonlyArrayDyn<'py, f32>> {
    if let Ok(a) = obj.cast::<PyArrayDyn<f32>>() {
        if a.is_c_contiguous() {
            return Ok(a.readonly());
        }
    }
    let np = py.import("numpy")?;
    let arr = np
        .call_method1("asarray", (obj,))
        .map_err(|e| PyValueError::new_err(format!("{name}: not an array of numbers ({e})")))?;
    let kind: String = arr.getattr("dtype")?.getattr("kind")?.extract()?;
    if !matches!(kind.as_str(), "f" | "i" | "u") {
        let dtype = arr.getattr("dtype")?.str()?.to_string();
        return Err(PyValueError::new_err(format!(
            "{name}: expected numbers, got an array of dtype {dtype}"
        )));
    }
    let f32_dtype = np.getattr("float32")?;
    let kw = pyo3::types::PyDict::new(py);
    kw.set_item("dtype", f32_dtype)?;
    let conv = np.call_method("ascontiguousarray", (arr,), Some(&kw))?;
    Ok(conv.cast_into::<PyArrayDyn<f32>>()?.readonly())
}

/// An integer C-contiguous view of `obj` as int64 (converted once unless it already is one).
pub fn i64_array<'py>(
    py: Python<'py>,
    obj: &Bound<'py, PyAny>,
    name: &str,
) -> PyResult<PyReadonlyArrayDyn<'py, i64>> {
    if let Ok(a) = obj.cast::<PyArrayDyn<i64>>() {
        if a.is_c_contiguous() {
            return Ok(a.readonly());
        }
    }
    let np = py.import("numpy")?;
    let arr = np
        .call_method1("asarray", (obj,))
        .map_err(|e| PyValueError::new_err(format!("{name}: not an array of integers ({e})")))?;
    let kind: String = arr.getattr("dtype")?.getattr("kind")?.extract()?;
    if !matches!(kind.as_str(), "i" | "u") {
        let dtype = arr.getattr("dtype")?.str()?.to_string();
        return Err(PyValueError::new_err(format!(
            "{name}: expected integer indices, got an array of dtype {dtype}"
        )));
    }
    let kw = pyo3::types::PyDict::new(py);
    kw.set_item("dtype", np.getattr("int64")?)?;
    let conv = np.call_method("ascontiguousarray", (arr,), Some(&kw))?;
    Ok(conv.cast_into::<PyArrayDyn<i64>>()?.readonly())
}

/// `name[i, j, ...]` for flat index `flat` of an array whose leading shape is `lead`.
pub fn index_name(name: &str, lead: &[usize], flat: usize) -> String {
    let mut idx = Vec::with_capacity(lead.len());
    let mut rest = flat;
    for &d in lead.iter().rev() {
        let d = d.max(1);
        idx.push(rest % d);
        rest /= d;
    }
    idx.reverse();
    let parts: Vec<String> = idx.iter().map(|i| i.to_string()).collect();
    format!("{name}[{}]", parts.join(", "))
}

fn fmt_shape(shape: &[usize]) -> String {
    match shape {
        [x] => format!("({x},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// Rays as the caller gave them: a float32 view of shape `(..., 6)` or `(..., 8)`.
pub struct RayInput<'py> {
    /// The data.
    pub array: PyReadonlyArrayDyn<'py, f32>,
    /// The leading shape (the shape of every output).
    pub lead: Vec<usize>,
    /// 6 or 8 columns.
    pub cols: usize,
}

impl RayInput<'_> {
    /// `(width, height)` for image-shaped `(H, W, C)` rays (the CLI's rule for rays files).
    pub fn image(&self) -> Option<(u32, u32)> {
        match self.lead[..] {
            [h, w] if h <= u32::MAX as usize && w <= u32::MAX as usize => {
                Some((w as u32, h as u32))
            }
            _ => None,
        }
    }
}

/// Reads `obj` as rays of shape `(..., 6)` or `(..., 8)`.
pub fn ray_input<'py>(
    py: Python<'py>,
    obj: &Bound<'py, PyAny>,
    name: &str,
) -> PyResult<RayInput<'py>> {
    let array = f32_array(py, obj, name)?;
    let shape = array.shape().to_vec();
    let cols = shape.last().copied().unwrap_or(0);
    if shape.is_empty() || !(cols == 6 || cols == 8) {
        return Err(PyValueError::new_err(format!(
            "{name}: shape {}; expected (..., 6) [ox, oy, oz, dx, dy, dz] or (..., 8) [..., tmin, tmax]",
            fmt_shape(&shape)
        )));
    }
    let lead = shape[..shape.len() - 1].to_vec();
    Ok(RayInput { array, lead, cols })
}

/// What is wrong with a ray (found while transposing).
#[derive(Clone, Copy, Debug)]
pub enum BadRay {
    /// NaN or infinite origin or direction.
    NonFinite,
    /// Direction (0, 0, 0).
    ZeroDirection,
    /// tmin or tmax is NaN.
    NanInterval,
}

impl BadRay {
    /// The `ValueError` for ray `flat` of `input`.
    pub fn to_err(self, input: &RayInput<'_>, name: &str, flat: usize) -> PyErr {
        let at = index_name(name, &input.lead, flat);
        let row = input
            .array
            .as_slice()
            .map(|s| s[flat * input.cols..(flat + 1) * input.cols].to_vec())
            .unwrap_or_default();
        PyValueError::new_err(match self {
            BadRay::NonFinite => {
                format!("{at}: non-finite origin or direction (NaN or infinity): {row:?}")
            }
            BadRay::ZeroDirection => format!("{at}: zero direction: {row:?}"),
            BadRay::NanInterval => format!("{at}: tmin or tmax is NaN: {row:?}"),
        })
    }
}

/// The interval rays get: their own columns (8) or `[0, +inf)` (6), narrowed by `tnear`/`tfar`
/// when given.
#[derive(Clone, Copy, Debug, Default)]
pub struct Interval {
    /// Lower bound applied to every ray.
    pub tnear: Option<f32>,
    /// Upper bound applied to every ray.
    pub tfar: Option<f32>,
}

/// Transposes `data` (rows of `cols` floats) into `b`, reusing its buffers, checking every ray as
/// the CLI checks a rays file (finite origin and direction, non-zero direction, no NaN interval).
/// Returns the first bad ray's index and fault. Runs in the current rayon pool.
pub fn fill_batch(
    b: &mut RayBatch,
    data: &[f32],
    cols: usize,
    iv: Interval,
) -> Result<(), (usize, BadRay)> {
    let n = data.len() / cols;
    for v in [
        &mut b.ox,
        &mut b.oy,
        &mut b.oz,
        &mut b.dx,
        &mut b.dy,
        &mut b.dz,
        &mut b.tmin,
        &mut b.tmax,
    ] {
        crate::mem::reuse(v, n);
    }
    b.layout = raysift::rays::RayLayout::Unknown;
    let bad = (
        b.ox.par_chunks_mut(BLOCK),
        b.oy.par_chunks_mut(BLOCK),
        b.oz.par_chunks_mut(BLOCK),
        b.dx.par_chunks_mut(BLOCK),
        b.dy.par_chunks_mut(BLOCK),
        b.dz.par_chunks_mut(BLOCK),
        b.tmin.par_chunks_mut(BLOCK),
        b.tmax.par_chunks_mut(BLOCK),
    )
        .into_par_iter()
        .enumerate()
        .filter_map(|(blk, (ox, oy, oz, dx, dy, dz, tmin, tmax))| {
            let start = blk * BLOCK;
            let rows = &data[start * cols..(start + ox.len()) * cols];
            let out = [ox, oy, oz, dx, dy, dz, tmin, tmax];
            let r = if cols == 8 {
                fill_block::<8>(rows, out, iv)
            } else {
                fill_block::<6>(rows, out, iv)
            };
            r.map(|(k, bad)| (start + k, bad))
        })
        .min_by_key(|&(i, _)| i);
    match bad {
        Some(bad) => Err(bad),
        None => Ok(()),
    }
}

/// What is wrong with one ray of `C` columns, if anything.
fn check_ray<const C: usize>(row: &[f32]) -> Option<BadRay> {
    if !row[..6].iter().all(|x| x.is_finite()) {
        Some(BadRay::NonFinite)
    } else if row[3] == 0.0 && row[4] == 0.0 && row[5] == 0.0 {
        Some(BadRay::ZeroDirection)
    } else if C == 8 && (row[6].is_nan() || row[7].is_nan()) {
        Some(BadRay::NanInterval)
    } else {
        None
    }
}

/// One block of rays (L2-sized): a branch-free check of every ray (the faulty one is looked for
/// only when there is one), then one pass per column, so the loops carry no early exits.
fn fill_block<const C: usize>(
    rows: &[f32],
    [ox, oy, oz, dx, dy, dz, tmin, tmax]: [&mut [f32]; 8],
    iv: Interval,
) -> Option<(usize, BadRay)> {
    let mut ok = true;
    for row in rows.chunks_exact(C) {
        let finite = row[..6].iter().fold(true, |a, x| a & x.is_finite());
        let moving = (row[3] != 0.0) | (row[4] != 0.0) | (row[5] != 0.0);
        let interval = C == 6 || !(row[6].is_nan() | row[7].is_nan());
        ok &= finite & moving & interval;
    }
    if !ok {
        return rows
            .chunks_exact(C)
            .enumerate()
            .find_map(|(k, row)| check_ray::<C>(row).map(|bad| (k, bad)));
    }
    for (c, col) in [ox, oy, oz, dx, dy, dz].into_iter().enumerate() {
        for (o, row) in col.iter_mut().zip(rows.chunks_exact(C)) {
            *o = row[c];
        }
    }
    // The caller's bounds narrow the rays' own interval (8 columns) or replace the default
    // [0, inf) (6 columns).
    if C == 8 {
        for ((lo, hi), row) in tmin
            .iter_mut()
            .zip(tmax.iter_mut())
            .zip(rows.chunks_exact(C))
        {
            *lo = iv.tnear.map_or(row[6], |t| row[6].max(t));
            *hi = iv.tfar.map_or(row[7], |t| row[7].min(t));
        }
    } else {
        tmin.fill(iv.tnear.unwrap_or(0.0));
        tmax.fill(iv.tfar.unwrap_or(f32::INFINITY));
    }
    None
}

/// Reads `(V, 3)` vertex positions, each finite.
pub fn vertices<'py>(
    py: Python<'py>,
    obj: &Bound<'py, PyAny>,
    name: &str,
) -> PyResult<Vec<glam::Vec3>> {
    let a = f32_array(py, obj, name)?;
    let shape = a.shape().to_vec();
    if shape.len() != 2 || shape[1] != 3 {
        return Err(PyValueError::new_err(format!(
            "{name}: shape {}; expected (V, 3)",
            fmt_shape(&shape)
        )));
    }
    let s = a.as_slice()?;
    if let Some(i) = s
        .chunks_exact(3)
        .position(|p| !p.iter().all(|x| x.is_finite()))
    {
        return Err(PyValueError::new_err(format!(
            "{name}[{i}]: non-finite coordinate (NaN or infinity): {:?}",
            &s[3 * i..3 * i + 3]
        )));
    }
    Ok(s.chunks_exact(3)
        .map(|p| glam::Vec3::new(p[0], p[1], p[2]))
        .collect())
}

/// Reads `(T, 3)` vertex indices, each in `0..vertex_count`.
pub fn triangles<'py>(
    py: Python<'py>,
    obj: &Bound<'py, PyAny>,
    name: &str,
    vertex_count: usize,
) -> PyResult<Vec<[u32; 3]>> {
    let a = i64_array(py, obj, name)?;
    let shape = a.shape().to_vec();
    if shape.len() != 2 || shape[1] != 3 {
        return Err(PyValueError::new_err(format!(
            "{name}: shape {}; expected (T, 3)",
            fmt_shape(&shape)
        )));
    }
    let s = a.as_slice()?;
    if let Some(k) = s
        .iter()
        .position(|&i| i < 0 || i as u64 >= vertex_count as u64)
    {
        return Err(PyValueError::new_err(format!(
            "{name}[{}, {}]: vertex index {} out of range (the vertices have {vertex_count} rows)",
            k / 3,
            k % 3,
            s[k]
        )));
    }
    Ok(s.chunks_exact(3)
        .map(|t| [t[0] as u32, t[1] as u32, t[2] as u32])
        .collect())
}

/// Reads a 4×4 (or 3×4) affine matrix, row-major as numpy writes it (`M @ [x, y, z, 1]`).
pub fn affine<'py>(
    py: Python<'py>,
    obj: &Bound<'py, PyAny>,
    name: &str,
) -> PyResult<glam::Affine3A> {
    let a = f32_array(py, obj, name)?;
    let shape = a.shape().to_vec();
    if !(shape == [4, 4] || shape == [3, 4]) {
        return Err(PyValueError::new_err(format!(
            "{name}: shape {}; expected a (4, 4) or (3, 4) affine matrix",
            fmt_shape(&shape)
        )));
    }
    let m = a.as_slice()?;
    if let Some(k) = m.iter().position(|x| !x.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "{name}[{}, {}]: non-finite entry {}",
            k / 4,
            k % 4,
            m[k]
        )));
    }
    if shape[0] == 4 && m[12..16] != [0.0, 0.0, 0.0, 1.0] {
        return Err(PyValueError::new_err(format!(
            "{name}: last row is {:?}; an affine transform's is [0, 0, 0, 1]",
            &m[12..16]
        )));
    }
    let col = |c: usize| glam::Vec3::new(m[c], m[4 + c], m[8 + c]);
    Ok(glam::Affine3A::from_mat3_translation(
        glam::Mat3::from_cols(col(0), col(1), col(2)),
        col(3),
    ))
}

/// Reads a 3-vector.
pub fn vec3<'py>(py: Python<'py>, obj: &Bound<'py, PyAny>, name: &str) -> PyResult<glam::Vec3> {
    let a = f32_array(py, obj, name)?;
    let s = a.as_slice()?;
    if a.shape() != [3] {
        return Err(PyValueError::new_err(format!(
            "{name}: shape {}; expected 3 numbers",
            fmt_shape(a.shape())
        )));
    }
    if !s.iter().all(|x| x.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "{name}: non-finite coordinate {s:?}"
        )));
    }
    Ok(glam::Vec3::new(s[0], s[1], s[2]))
}
