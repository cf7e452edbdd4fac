//! The pyo3 binding `nrdepth._core`: converts and validates, nothing else.
//!
//! Parameters cross as plain dicts (the Python dataclasses' `as_dict`), arrays
//! as C-contiguous numpy arrays. Every core `InvalidArgument` becomes a
//! `ValueError("name: message")`; heavy work runs with the GIL released.

use std::path::PathBuf;

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::error::InvalidArgument;
use crate::params::{Range, SurfaceConfig, SurfaceParams};
use crate::synthesis::{self, check_sizes, clip_len};
use crate::{image_io, mesh};

fn value_error(e: InvalidArgument) -> PyErr {
    PyValueError::new_err(e.to_string())
}

fn field<'py, T: for<'a> FromPyObjectOwned<'py>>(d: &Bound<'py, PyDict>, owner: &str, key: &str) -> PyResult<T> {
    let item = d
        .get_item(key)?
        .ok_or_else(|| PyValueError::new_err(format!("{owner}.{key}: missing")))?;
    item.extract::<T>().map_err(|e| {
        let e: PyErr = e.into();
        PyTypeError::new_err(format!("{owner}.{key}: expected {}, got {e}", std::any::type_name::<T>()))
    })
}

fn params_from_dict(d: &Bound<'_, PyDict>, owner: &str) -> PyResult<SurfaceParams> {
    Ok(SurfaceParams {
        intensity: field(d, owner, "intensity")?,
        constraint: field(d, owner, "constraint")?,
        folding: field(d, owner, "folding")?,
        flexibility: field(d, owner, "flexibility")?,
        orientation: field(d, owner, "orientation")?,
        speeds: field(d, owner, "speeds")?,
        phase_seed: field(d, owner, "phase_seed")?,
        rotation: field(d, owner, "rotation")?,
        rotation_rate: field(d, owner, "rotation_rate")?,
        drift: field(d, owner, "drift")?,
    })
}

fn params_to_dict<'py>(py: Python<'py>, p: &SurfaceParams) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("intensity", p.intensity)?;
    d.set_item("constraint", p.constraint)?;
    d.set_item("folding", p.folding)?;
    d.set_item("flexibility", p.flexibility)?;
    d.set_item("orientation", p.orientation)?;
    d.set_item("speeds", p.speeds)?;
    d.set_item("phase_seed", p.phase_seed)?;
    d.set_item("rotation", p.rotation)?;
    d.set_item("rotation_rate", p.rotation_rate)?;
    d.set_item("drift", p.drift)?;
    Ok(d)
}

fn config_from_dict(d: &Bound<'_, PyDict>) -> PyResult<SurfaceConfig> {
    let range = |key: &str| -> PyResult<Range> {
        let (lo, hi): (f64, f64) = field(d, "config", key)?;
        Ok(Range::new(lo, hi))
    };
    Ok(SurfaceConfig {
        intensity: range("intensity")?,
        constraint: range("constraint")?,
        folding: range("folding")?,
        flexibility: range("flexibility")?,
        orientation_eigenvalues: range("orientation_eigenvalues")?,
        speed: range("speed")?,
        tilt: range("tilt")?,
        spin: range("spin")?,
        tilt_rate: range("tilt_rate")?,
        spin_rate: range("spin_rate")?,
        drift_xy: range("drift_xy")?,
        drift_z: range("drift_z")?,
    })
}

fn config_to_dict<'py>(py: Python<'py>, c: &SurfaceConfig) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (key, r) in [
        ("intensity", c.intensity),
        ("constraint", c.constraint),
        ("folding", c.folding),
        ("flexibility", c.flexibility),
        ("orientation_eigenvalues", c.orientation_eigenvalues),
        ("speed", c.speed),
        ("tilt", c.tilt),
        ("spin", c.spin),
        ("tilt_rate", c.tilt_rate),
        ("spin_rate", c.spin_rate),
        ("drift_xy", c.drift_xy),
        ("drift_z", c.drift_z),
    ] {
        d.set_item(key, (r.lo, r.hi))?;
    }
    Ok(d)
}

/// The default `SurfaceConfig` ranges as a dict of (lo, hi).
#[pyfunction]
fn default_surface_config(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    config_to_dict(py, &SurfaceConfig::default())
}

/// Draw one `SurfaceParams` dict from `config` (a dict of (lo, hi) ranges).
#[pyfunction]
fn sample_surface_params<'py>(py: Python<'py>, seed: u64, config: &Bound<'py, PyDict>) -> PyResult<Bound<'py, PyDict>> {
    let config = config_from_dict(config)?;
    let params = config.sample(seed).map_err(value_error)?;
    params_to_dict(py, &params)
}

/// Raise `ValueError` naming the field if `params` is outside its domain.
#[pyfunction]
fn validate_surface_params(params: &Bound<'_, PyDict>) -> PyResult<()> {
    params_from_dict(params, "params")?.validate().map_err(value_error)
}

/// Raise `ValueError` naming the range if `config` is not a valid `SurfaceConfig`.
#[pyfunction]
fn validate_surface_config(config: &Bound<'_, PyDict>) -> PyResult<()> {
    config_from_dict(config)?.validate().map_err(value_error)
}

/// Vertex positions of one clip, float32 (frames, grid, grid, 3).
#[pyfunction]
fn synthesize_surface<'py>(py: Python<'py>, params: &Bound<'py, PyDict>, frames: i64, grid: i64) -> PyResult<Bound<'py, PyAny>> {
    let (frames, grid) = check_sizes(frames, grid).map_err(value_error)?;
    let params = params_from_dict(params, "params")?;
    params.validate().map_err(value_error)?;
    let data = py.detach(|| synthesis::synthesize(&params, frames, grid)).map_err(value_error)?;
    Ok(PyArray1::from_vec(py, data).reshape([frames, grid, grid, 3])?.into_any())
}

/// Vertex positions of many clips in parallel, float32 (n, frames, grid, grid, 3).
#[pyfunction]
fn synthesize_surfaces<'py>(py: Python<'py>, params: &Bound<'py, PyList>, frames: i64, grid: i64) -> PyResult<Bound<'py, PyAny>> {
    let (frames, grid) = check_sizes(frames, grid).map_err(value_error)?;
    let params = params
        .iter()
        .enumerate()
        .map(|(i, d)| {
            let d = d.cast_into::<PyDict>().map_err(|_| PyTypeError::new_err(format!("params[{i}]: expected a dict")))?;
            params_from_dict(&d, &format!("params[{i}]"))
        })
        .collect::<PyResult<Vec<_>>>()?;
    let n = params.len();
    let len = n
        .checked_mul(clip_len(frames, grid))
        .filter(|&l| l <= MAX_VALUES)
        .ok_or_else(|| PyValueError::new_err(format!("params: {n} clips of {frames}×{grid}×{grid} exceed {MAX_VALUES} values per call")))?;
    let data = py
        .detach(|| {
            let mut out = vec![0.0f32; len];
            synthesis::synthesize_batch(&params, frames, grid, &mut out).map(|_| out)
        })
        .map_err(value_error)?;
    Ok(PyArray1::from_vec(py, data).reshape([n, frames, grid, grid, 3])?.into_any())
}

/// At most 2³¹ float32 values (8 GiB) in one synthesis call.
const MAX_VALUES: usize = 1 << 31;

/// Triangle indices of the grid mesh, uint32 (2 (grid − 1)², 3).
#[pyfunction]
fn grid_triangles(py: Python<'_>, grid: i64) -> PyResult<Bound<'_, PyAny>> {
    let tris = mesh::grid_triangles(grid).map_err(value_error)?;
    let n = tris.len() / 3;
    Ok(PyArray1::from_vec(py, tris).reshape([n, 3])?.into_any())
}

/// Write a uint8 (H, W, 3) image as PNG, atomically.
#[pyfunction]
fn write_png(py: Python<'_>, path: PathBuf, image: PyReadonlyArray3<'_, u8>) -> PyResult<()> {
    let shape = image.shape().to_vec();
    if shape[2] != 3 {
        return Err(PyValueError::new_err(format!("image: expected shape (H, W, 3), got {shape:?}")));
    }
    let pixels = image.as_slice().map_err(|_| PyValueError::new_err("image: expected a C-contiguous array"))?;
    py.detach(|| image_io::write_png_rgb(&path, pixels, shape[0], shape[1])).map_err(value_error)
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(default_surface_config, m)?)?;
    m.add_function(wrap_pyfunction!(sample_surface_params, m)?)?;
    m.add_function(wrap_pyfunction!(validate_surface_params, m)?)?;
    m.add_function(wrap_pyfunction!(validate_surface_config, m)?)?;
    m.add_function(wrap_pyfunction!(synthesize_surface, m)?)?;
    m.add_function(wrap_pyfunction!(synthesize_surfaces, m)?)?;
    m.add_function(wrap_pyfunction!(grid_triangles, m)?)?;
    m.add_function(wrap_pyfunction!(write_png, m)?)?;
    m.add("FFT_PERIOD", synthesis::PERIOD)?;
    m.add("W_RADIUS", synthesis::W_RADIUS)?;
    m.add("SPECTRUM_CUTOFF", synthesis::SPECTRUM_CUTOFF)?;
    m.add("MAX_GRID", synthesis::MAX_GRID)?;
    m.add("MAX_FRAMES", synthesis::MAX_FRAMES)?;
    Ok(())
}
