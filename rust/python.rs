//! The pyo3 binding `nrdepth._core`: converts and validates, nothing else.
//!
//! Parameters cross as plain dicts (the Python dataclasses' `as_dict`), arrays
//! as C-contiguous numpy arrays. Every core `InvalidArgument` becomes a
//! `ValueError("name: message")`; heavy work runs with the GIL released.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use rayon::ThreadPool;

use crate::bvh;
use crate::error::InvalidArgument;
use crate::generate::{self, ClipParams, GeneratorConfig, TextureChoice};
use crate::geometry::{CameraConfig, View};
use crate::params::{Range, SurfaceConfig, SurfaceParams};
use crate::raster::{self, Light, LightKind, Material, Scene, Shading, Texture};
use crate::backdrop::{BackdropConfig, BackdropParams};
use crate::sheet::{SheetConfig, SheetParams};
use crate::synthesis::{self, check_sizes, clip_len};
use crate::textures::{self, TextureBank, TextureFamily};
use crate::{image_io, mesh};

/// The rayon pool of this process. A forked child (a DataLoader worker)
/// inherits the parent's pool without its threads, so a new pool is made
/// whenever the process id changes; the stale one is leaked, never joined.
fn pool() -> PyResult<Arc<ThreadPool>> {
    static POOL: Mutex<Option<(u32, Arc<ThreadPool>)>> = Mutex::new(None);
    let pid = std::process::id();
    let mut guard = POOL.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((owner, pool)) = guard.as_ref() {
        if *owner == pid {
            return Ok(pool.clone());
        }
    }
    let pool = Arc::new(rayon::ThreadPoolBuilder::new().build().map_err(|e| PyRuntimeError::new_err(format!("cannot start threads: {e}")))?);
    if let Some(stale) = guard.replace((pid, pool.clone())) {
        std::mem::forget(stale);
    }
    Ok(pool)
}

/// Run `f` without the GIL on this process's pool.
fn parallel<T: Send>(py: Python<'_>, f: impl FnOnce() -> T + Send) -> PyResult<T> {
    let pool = pool()?;
    Ok(py.detach(|| pool.install(f)))
}

/// [`parallel`] for long work that watches `cancel`: `f` runs on a helper
/// thread while this (the calling, usually main) thread checks Python's
/// signals every 50 ms; on Ctrl-C (or any signal handler raising) it sets
/// `cancel`, waits for `f` to stop and raises the handler's exception.
fn parallel_interruptible<T: Send>(py: Python<'_>, cancel: &AtomicBool, f: impl FnOnce() -> T + Send) -> PyResult<T> {
    let pool = pool()?;
    std::thread::scope(|scope| {
        let (sender, mut receiver) = mpsc::channel();
        scope.spawn(move || {
            let _ = sender.send(pool.install(f));
        });
        loop {
            // The receiver goes into the GIL-free closure and comes back (it is Send, not Sync).
            let (result, back) = py.detach(move || (receiver.recv_timeout(Duration::from_millis(50)), receiver));
            receiver = back;
            match result {
                Ok(value) => return Ok(value),
                Err(RecvTimeoutError::Timeout) => {
                    if let Err(signal) = py.check_signals() {
                        cancel.store(true, Ordering::Relaxed);
                        let _ = py.detach(move || receiver.recv());
                        return Err(signal);
                    }
                }
                Err(RecvTimeoutError::Disconnected) => return Err(PyRuntimeError::new_err("worker thread failed")),
            }
        }
    })
}

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

/// A `(lo, hi)` range field of a config dict.
fn range_field(d: &Bound<'_, PyDict>, key: &str) -> PyResult<Range> {
    let (lo, hi): (f64, f64) = field(d, "config", key)?;
    Ok(Range::new(lo, hi))
}

/// Store ranges as `(lo, hi)` tuples.
fn set_ranges(d: &Bound<'_, PyDict>, ranges: &[(&str, Range)]) -> PyResult<()> {
    for (key, r) in ranges {
        d.set_item(*key, (r.lo, r.hi))?;
    }
    Ok(())
}

fn config_from_dict(d: &Bound<'_, PyDict>) -> PyResult<SurfaceConfig> {
    let range = |key: &str| range_field(d, key);
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
    set_ranges(&d, &[
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
    ])?;
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
    let data = parallel(py, || synthesis::synthesize(&params, frames, grid))?.map_err(value_error)?;
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
    let data = parallel(py, || {
        let mut out = vec![0.0f32; len];
        synthesis::synthesize_batch(&params, frames, grid, &mut out).map(|_| out)
    })?
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

/// Write a uint16 (H, W) grayscale image as a 16-bit PNG, atomically.
#[pyfunction]
fn write_png16(py: Python<'_>, path: PathBuf, image: PyReadonlyArray2<'_, u16>) -> PyResult<()> {
    let shape = image.shape().to_vec();
    let pixels = image.as_slice().map_err(|_| PyValueError::new_err("image: expected a C-contiguous array"))?;
    py.detach(|| image_io::write_png_gray16(&path, pixels, shape[0], shape[1])).map_err(value_error)
}

// ------------------------------------------------------------------ rendering

fn vec3_rows<'a>(name: &str, a: &'a PyReadonlyArray2<'_, f32>) -> PyResult<&'a [[f32; 3]]> {
    rows::<f32, 3>(name, a)
}

fn rows<'a, T: numpy::Element, const N: usize>(name: &str, a: &'a PyReadonlyArray2<'_, T>) -> PyResult<&'a [[T; N]]> {
    let shape = a.shape();
    if shape[1] != N {
        return Err(PyValueError::new_err(format!("{name}: expected shape (n, {N}), got {shape:?}")));
    }
    let flat = a.as_slice().map_err(|_| PyValueError::new_err(format!("{name}: expected a C-contiguous array")))?;
    Ok(flat.as_chunks::<N>().0)
}

fn view_from(size: (i64, i64), window: [f32; 4], camera_z: f32, pinhole: Option<[f32; 2]>) -> PyResult<View> {
    let (h, w) = size;
    if h < 1 || w < 1 {
        return Err(PyValueError::new_err(format!("size: expected (H, W) >= 1, got ({h}, {w})")));
    }
    let view = View::new(h as usize, w as usize, window, camera_z).map_err(value_error)?;
    match pinhole {
        None => Ok(view),
        Some(xy) => view.with_pinhole(xy).map_err(value_error),
    }
}

fn light_from_dict(d: &Bound<'_, PyAny>, i: usize) -> PyResult<Light> {
    let owner = format!("lights[{i}]");
    let d = d.cast::<PyDict>().map_err(|_| PyTypeError::new_err(format!("{owner}: expected a dict")))?;
    let kind: String = field(d, &owner, "kind")?;
    let kind = match kind.as_str() {
        "directional" => LightKind::Directional,
        "point" => LightKind::Point,
        other => return Err(PyValueError::new_err(format!("{owner}.kind: expected 'directional' or 'point', got {other:?}"))),
    };
    Ok(Light { kind, vector: field(d, &owner, "vector")?, intensity: field(d, &owner, "intensity")? })
}

fn light_to_dict<'py>(py: Python<'py>, l: &Light) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("kind", if l.kind == LightKind::Point { "point" } else { "directional" })?;
    d.set_item("vector", l.vector)?;
    d.set_item("intensity", l.intensity)?;
    Ok(d)
}

fn material_from_dict(d: &Bound<'_, PyDict>) -> PyResult<Material> {
    Ok(Material {
        ambient: field(d, "material", "ambient")?,
        diffuse: field(d, "material", "diffuse")?,
        specular: field(d, "material", "specular")?,
        shininess: field(d, "material", "shininess")?,
    })
}

fn material_to_dict<'py>(py: Python<'py>, m: &Material) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("ambient", m.ambient)?;
    d.set_item("diffuse", m.diffuse)?;
    d.set_item("specular", m.specular)?;
    d.set_item("shininess", m.shininess)?;
    Ok(d)
}

fn array2<'py, T: numpy::Element>(py: Python<'py>, data: Vec<T>, rows: usize, cols: usize) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyArray1::from_vec(py, data).reshape([rows, cols])?.into_any())
}

/// Render a mesh: (image, coverage, depth at pixel centres), each (H, W) float32.
#[pyfunction]
#[pyo3(signature = (vertices, triangles, uv, texture, size, window, lights, material, supersample, camera_z, shading, pinhole=None))]
#[allow(clippy::too_many_arguments)]
fn render<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f32>,
    triangles: PyReadonlyArray2<'py, u32>,
    uv: PyReadonlyArray2<'py, f32>,
    texture: PyReadonlyArray2<'py, f32>,
    size: (i64, i64),
    window: [f32; 4],
    lights: &Bound<'py, PyList>,
    material: &Bound<'py, PyDict>,
    supersample: i64,
    camera_z: f32,
    shading: &str,
    pinhole: Option<[f32; 2]>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let shading = Shading::from_name(shading).map_err(value_error)?;
    let view = view_from(size, window, camera_z, pinhole)?;
    let (v, t, uvs) = (vec3_rows("vertices", &vertices)?, rows::<u32, 3>("triangles", &triangles)?, rows::<f32, 2>("uv", &uv)?);
    let lights = lights.iter().enumerate().map(|(i, d)| light_from_dict(&d, i)).collect::<PyResult<Vec<_>>>()?;
    let material = material_from_dict(material)?;
    let tex_shape = texture.shape().to_vec();
    let texels = texture.as_slice().map_err(|_| PyValueError::new_err("texture: expected a C-contiguous array"))?;
    let texture = Texture::new(tex_shape[0], tex_shape[1], texels).map_err(value_error)?;
    if !(1..=raster::MAX_SUPERSAMPLE as i64).contains(&supersample) {
        return Err(PyValueError::new_err(format!("supersample: expected 1..={}, got {supersample}", raster::MAX_SUPERSAMPLE)));
    }
    let scene = Scene { view, supersample: supersample as usize, lights: &lights, material, texture: &texture, shading };
    let frame = parallel(py, || raster::render(v, t, uvs, &scene))?.map_err(value_error)?;
    let (h, w) = (view.height, view.width);
    Ok((array2(py, frame.image, h, w)?, array2(py, frame.coverage, h, w)?, array2(py, frame.depth, h, w)?))
}

/// Ray-cast depth (H, W) float32 of any mesh; NaN where a ray misses.
#[pyfunction]
#[pyo3(signature = (vertices, triangles, size, window, camera_z, pinhole=None))]
fn raycast_depth<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f32>,
    triangles: PyReadonlyArray2<'py, u32>,
    size: (i64, i64),
    window: [f32; 4],
    camera_z: f32,
    pinhole: Option<[f32; 2]>,
) -> PyResult<Bound<'py, PyAny>> {
    let view = view_from(size, window, camera_z, pinhole)?;
    let (v, t) = (vec3_rows("vertices", &vertices)?, rows::<u32, 3>("triangles", &triangles)?);
    let depth = parallel(py, || bvh::raycast_depth(v, t, &view))?.map_err(value_error)?;
    array2(py, depth, view.height, view.width)
}

/// A procedural texture (size, size) float32 in [0, 1].
#[pyfunction]
fn procedural_texture<'py>(py: Python<'py>, family: &str, seed: u64, size: i64) -> PyResult<Bound<'py, PyAny>> {
    let family = TextureFamily::from_name(family).map_err(|e| PyValueError::new_err(format!("family: {}", e.message)))?;
    let size = crate::error::size_in("size", size, 2, 4096).map_err(value_error)?;
    let mut texture = Texture::default();
    py.detach(|| textures::procedural(family, seed, size, &mut texture));
    array2(py, texture.to_vec(), size, size)
}

/// Names of the procedural texture families.
#[pyfunction]
fn texture_families() -> Vec<&'static str> {
    textures::FAMILIES.iter().map(|f| f.name()).collect()
}

// ------------------------------------------------------------------ generation

fn generator_config_from_dict(d: &Bound<'_, PyDict>) -> PyResult<GeneratorConfig> {
    let range = |key: &str| range_field(d, key);
    let size = |key: &str| -> PyResult<usize> {
        let v: i64 = field(d, "config", key)?;
        usize::try_from(v).map_err(|_| PyValueError::new_err(format!("config.{key}: expected a non-negative integer, got {v}")))
    };
    let surface: Bound<'_, PyDict> = field(d, "config", "surface")?;
    let families: Vec<String> = field(d, "config", "texture_families")?;
    let light_count: (i64, i64) = field(d, "config", "light_count")?;
    let config = GeneratorConfig {
        frames: size("frames")?,
        size: size("size")?,
        grid: size("grid")?,
        supersample: size("supersample")?,
        surface: config_from_dict(&surface)?,
        window_width: range("window_width")?,
        window_offset: range("window_offset")?,
        light_count: (light_count.0.max(0) as usize, light_count.1.max(0) as usize),
        light_azimuth: range("light_azimuth")?,
        light_elevation: range("light_elevation")?,
        light_intensity: range("light_intensity")?,
        point_light_probability: field(d, "config", "point_light_probability")?,
        point_light_distance: range("point_light_distance")?,
        ambient: range("ambient")?,
        diffuse: range("diffuse")?,
        specular: range("specular")?,
        shininess: range("shininess")?,
        shading: {
            let name: String = field(d, "config", "shading")?;
            Shading::from_name(&name).map_err(|e| PyValueError::new_err(format!("config.{e}")))?
        },
        texture_families: families.iter().map(|f| TextureFamily::from_name(f)).collect::<Result<_, _>>().map_err(|e| PyValueError::new_err(format!("config.{e}")))?,
        texture_size: size("texture_size")?,
        noise_std: range("noise_std")?,
        blur: range("blur")?,
        gamma: range("gamma")?,
        max_redraws: size("max_redraws")?,
        sheet: {
            let bends: (i64, i64) = field(d, "config", "sheet_bends")?;
            let count = |v: i64| usize::try_from(v).map_err(|_| PyValueError::new_err(format!("config.sheet_bends: expected counts >= 0, got {bends:?}")));
            SheetConfig {
                probability: field(d, "config", "sheet_probability")?,
                bends: (count(bends.0)?, count(bends.1)?),
                bend_angle: range("sheet_bend_angle")?,
                bend_width: range("sheet_bend_width")?,
                fold_probability: field(d, "config", "sheet_fold_probability")?,
                fold_angle: range("sheet_fold_angle")?,
                fold_width: range("sheet_fold_width")?,
                centre: range("sheet_centre")?,
                centre_drift: range("sheet_centre_drift")?,
                axis_rate: range("sheet_axis_rate")?,
                relief: range("sheet_relief")?,
                phases: size("sheet_phases")?,
                flat_start: field(d, "config", "sheet_flat_start")?,
            }
        },
        backdrop: BackdropConfig {
            probability: field(d, "config", "backdrop_probability")?,
            window_width: range("backdrop_window_width")?,
            window_offset: range("backdrop_window_offset")?,
            min_cover: field(d, "config", "backdrop_min_cover")?,
            brightness: range("backdrop_brightness")?,
            flat_probability: field(d, "config", "backdrop_flat_probability")?,
        },
        camera: CameraConfig { fov: range("camera_fov")?, crop_share: range("crop_share")?, probability: field(d, "config", "camera_probability")? },
    };
    config.validate().map_err(value_error)?;
    Ok(config)
}

/// The default `GeneratorConfig` as a dict (without `textures`).
#[pyfunction]
fn default_generator_config(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let c = GeneratorConfig::default();
    let d = PyDict::new(py);
    d.set_item("frames", c.frames)?;
    d.set_item("size", c.size)?;
    d.set_item("grid", c.grid)?;
    d.set_item("supersample", c.supersample)?;
    d.set_item("surface", config_to_dict(py, &c.surface)?)?;
    set_ranges(&d, &[
        ("window_width", c.window_width),
        ("window_offset", c.window_offset),
        ("light_azimuth", c.light_azimuth),
        ("light_elevation", c.light_elevation),
        ("light_intensity", c.light_intensity),
        ("point_light_distance", c.point_light_distance),
        ("ambient", c.ambient),
        ("diffuse", c.diffuse),
        ("specular", c.specular),
        ("shininess", c.shininess),
        ("noise_std", c.noise_std),
        ("blur", c.blur),
        ("gamma", c.gamma),
    ])?;
    d.set_item("light_count", c.light_count)?;
    d.set_item("point_light_probability", c.point_light_probability)?;
    d.set_item("shading", c.shading.name())?;
    d.set_item("texture_families", c.texture_families.iter().map(|f| f.name()).collect::<Vec<_>>())?;
    d.set_item("texture_size", c.texture_size)?;
    d.set_item("max_redraws", c.max_redraws)?;
    let sheet = &c.sheet;
    d.set_item("sheet_probability", sheet.probability)?;
    d.set_item("sheet_bends", sheet.bends)?;
    d.set_item("sheet_fold_probability", sheet.fold_probability)?;
    d.set_item("sheet_phases", sheet.phases)?;
    d.set_item("sheet_flat_start", sheet.flat_start)?;
    set_ranges(&d, &[
        ("sheet_bend_angle", sheet.bend_angle),
        ("sheet_bend_width", sheet.bend_width),
        ("sheet_fold_angle", sheet.fold_angle),
        ("sheet_fold_width", sheet.fold_width),
        ("sheet_centre", sheet.centre),
        ("sheet_centre_drift", sheet.centre_drift),
        ("sheet_axis_rate", sheet.axis_rate),
        ("sheet_relief", sheet.relief),
    ])?;
    let backdrop = &c.backdrop;
    d.set_item("backdrop_probability", backdrop.probability)?;
    d.set_item("backdrop_min_cover", backdrop.min_cover)?;
    d.set_item("backdrop_flat_probability", backdrop.flat_probability)?;
    d.set_item("camera_probability", c.camera.probability)?;
    set_ranges(&d, &[
        ("backdrop_window_width", backdrop.window_width),
        ("backdrop_window_offset", backdrop.window_offset),
        ("backdrop_brightness", backdrop.brightness),
        ("camera_fov", c.camera.fov),
        ("crop_share", c.camera.crop_share),
    ])?;
    Ok(d)
}

/// Validate a generator config dict; raises ValueError naming the field.
#[pyfunction]
fn validate_generator_config(config: &Bound<'_, PyDict>) -> PyResult<()> {
    generator_config_from_dict(config).map(|_| ())
}

/// Decoded texture folders, by (folder, its modification time, crop size):
/// a folder such as DTD is decoded once per process, again if files change.
fn texture_bank(dir: &Path, crop: usize) -> PyResult<Arc<TextureBank>> {
    type Key = (PathBuf, Option<std::time::SystemTime>, usize);
    static BANKS: Mutex<Option<HashMap<Key, Arc<TextureBank>>>> = Mutex::new(None);
    let key = (dir.to_path_buf(), std::fs::metadata(dir).and_then(|m| m.modified()).ok(), crop);
    if let Some(bank) = BANKS.lock().unwrap_or_else(|e| e.into_inner()).get_or_insert_with(HashMap::new).get(&key) {
        return Ok(bank.clone());
    }
    let bank = Arc::new(TextureBank::load_dir(dir, crop).map_err(value_error)?);
    BANKS.lock().unwrap_or_else(|e| e.into_inner()).get_or_insert_with(HashMap::new).insert(key, bank.clone());
    Ok(bank)
}

fn clip_to_dict<'py>(py: Python<'py>, p: &ClipParams, bank: Option<&TextureBank>) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("surface", params_to_dict(py, &p.surface)?)?;
    d.set_item("window", p.window)?;
    d.set_item("lights", p.lights.iter().map(|l| light_to_dict(py, l)).collect::<PyResult<Vec<_>>>()?)?;
    d.set_item("material", material_to_dict(py, &p.material)?)?;
    let texture = PyDict::new(py);
    match &p.texture {
        TextureChoice::Procedural { family, seed } => {
            texture.set_item("family", family.name())?;
            texture.set_item("seed", *seed)?;
        }
        TextureChoice::Image { index, top, left } => {
            let path = bank.map(|b| b.paths[*index].display().to_string());
            texture.set_item("image", path)?;
            texture.set_item("top", *top)?;
            texture.set_item("left", *left)?;
        }
    }
    d.set_item("texture", texture)?;
    d.set_item("noise_std", p.noise_std)?;
    d.set_item("noise_seed", p.noise_seed)?;
    d.set_item("blur", p.blur)?;
    d.set_item("gamma", p.gamma)?;
    d.set_item("sheet", p.sheet.as_ref().map(|sheet| sheet_to_dict(py, sheet)).transpose()?)?;
    d.set_item("backdrop", p.backdrop.as_ref().map(|b| backdrop_to_dict(py, b)).transpose()?)?;
    let pinhole = p.pinhole.map(|pinhole| -> PyResult<_> {
        let d = PyDict::new(py);
        d.set_item("xy", pinhole.xy)?;
        d.set_item("camera_z", pinhole.camera_z)?;
        Ok(d)
    });
    d.set_item("pinhole", pinhole.transpose()?)?;
    d.set_item("redraws", p.redraws)?;
    Ok(d)
}

fn backdrop_to_dict<'py>(py: Python<'py>, b: &BackdropParams) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("family", b.texture.map(|(family, _)| family.name()))?;
    d.set_item("seed", b.texture.map(|(_, seed)| seed))?;
    d.set_item("brightness", b.brightness)?;
    Ok(d)
}

fn sheet_to_dict<'py>(py: Python<'py>, sheet: &SheetParams) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("axis", &sheet.axis)?;
    let terms = sheet
        .terms
        .iter()
        .map(|term| {
            let t = PyDict::new(py);
            t.set_item("angle", &term.angle)?;
            t.set_item("centre", &term.centre)?;
            t.set_item("width", term.width)?;
            Ok(t)
        })
        .collect::<PyResult<Vec<_>>>()?;
    d.set_item("terms", terms)?;
    d.set_item("relief", sheet.relief)?;
    Ok(d)
}

/// Clips `start .. start + n`: (video u8 (n, T, H, W), depth f32 (n, T, H, W),
/// params list, with `vertices` their meshes f32 (n, T, grid, grid, 3), else None).
#[pyfunction]
#[pyo3(signature = (n, seed, start, config, textures=None, vertices=false))]
fn generate_clips<'py>(
    py: Python<'py>,
    n: i64,
    seed: u64,
    start: u64,
    config: &Bound<'py, PyDict>,
    textures: Option<PathBuf>,
    vertices: bool,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyList>, Option<Bound<'py, PyAny>>)> {
    let config = generator_config_from_dict(config)?;
    let n = crate::error::size_in("n", n, 0, 1 << 24).map_err(value_error)?;
    let len = n
        .checked_mul(config.clip_pixels())
        .filter(|&l| l <= MAX_VALUES)
        .ok_or_else(|| PyValueError::new_err(format!("n: {n} clips exceed {MAX_VALUES} pixels per call; generate in smaller batches")))?;
    let bank = textures.as_deref().map(|dir| texture_bank(dir, config.texture_size)).transpose()?;
    let mesh_len = n
        .checked_mul(clip_len(config.frames, config.grid))
        .filter(|&l| !vertices || l <= MAX_VALUES)
        .ok_or_else(|| PyValueError::new_err(format!("n: the meshes of {n} clips exceed {MAX_VALUES} values per call; generate in smaller batches")))?;
    // numpy's allocator backs large arrays with transparent huge pages where
    // the kernel offers them (`madvise`): a batch's first touch of its output
    // then costs a few page faults, not one per 4 KiB.
    let (video, depth) = (PyArray1::<u8>::zeros(py, len, false), PyArray1::<f32>::zeros(py, len, false));
    let meshes = vertices.then(|| PyArray1::<f32>::zeros(py, mesh_len, false));
    let params = {
        let (mut video, mut depth) = (video.readwrite(), depth.readwrite());
        let mut meshes = meshes.as_ref().map(|m| m.readwrite());
        let meshes = meshes.as_mut().map(|m| m.as_slice_mut()).transpose()?;
        let (video, depth) = (video.as_slice_mut()?, depth.as_slice_mut()?);
        let cancel = AtomicBool::new(false);
        parallel_interruptible(py, &cancel, || generate::generate_clips_until(&config, bank.as_deref(), seed, start, n, video, depth, meshes, &cancel))?.map_err(value_error)?
    };
    let (t, s, g) = (config.frames, config.size, config.grid);
    let (video, depth) = (video.reshape([n, t, s, s])?.into_any(), depth.reshape([n, t, s, s])?.into_any());
    let meshes = meshes.map(|m| m.reshape([n, t, g, g, 3]).map(|m| m.into_any())).transpose()?;
    let params = PyList::new(py, params.iter().map(|p| clip_to_dict(py, p, bank.as_deref())).collect::<PyResult<Vec<_>>>()?)?;
    Ok((video, depth, params, meshes))
}

// ------------------------------------------------------------------ stitching

/// Padding, padded shape and patch origins of a video shape.
#[pyfunction]
fn patch_layout(shape: (i64, i64, i64), patch: (i64, i64, i64)) -> PyResult<(Vec<usize>, Vec<usize>, Vec<[usize; 3]>)> {
    let dims = |name: &str, v: (i64, i64, i64)| -> PyResult<[usize; 3]> {
        let a = [v.0, v.1, v.2];
        if a.iter().any(|&x| !(1..=1 << 20).contains(&x)) {
            return Err(PyValueError::new_err(format!("{name}: expected three sizes in [1, 2**20], got {a:?}")));
        }
        Ok(a.map(|x| x as usize))
    };
    let layout = crate::stitch::Layout::new(dims("shape", shape)?, dims("patch", patch)?).map_err(value_error)?;
    Ok((layout.pad.to_vec(), layout.padded.to_vec(), layout.origins()))
}

/// The two ways of aligning the patches (`crate::stitch`, `crate::joint`).
enum Alignment {
    Coarse(crate::stitch::Stitcher),
    Joint(crate::joint::JointStitcher),
}

/// Streaming COLA stitcher over a coarse depth (T, H, W) with the named
/// window (`"hann"` or `"triangle"`): `add` chunks of patches (N, Lt, Ls, Ls)
/// with their padded origins (N, 3), then `finish`.
/// Without `coarse_weight`, each patch is aligned to the coarse depth on its
/// own (the paper); with it, all together (`crate::joint`: origins on the
/// layout's grid, each once, and every patch added before `finish`), each
/// patch's GBRs tied over time by `temporal_weight`. The joint alignment
/// also streams: given `frames` (the video's T), `coarse` may hold only the
/// first frames, the rest coming by `push_coarse`, and `take` returns the
/// frames stitched so far and releases them.
#[pyclass(name = "Stitcher", module = "nrdepth._core")]
struct PyStitcher {
    inner: Option<Alignment>,
    shape: [usize; 3],
    patch: [usize; 3],
}

#[pymethods]
impl PyStitcher {
    #[new]
    #[pyo3(signature = (coarse, patch, window, coarse_weight=None, temporal_weight=0.0, frames=None))]
    fn new(
        py: Python<'_>,
        coarse: PyReadonlyArray3<'_, f32>,
        patch: (i64, i64, i64),
        window: &str,
        coarse_weight: Option<f64>,
        temporal_weight: f64,
        frames: Option<i64>,
    ) -> PyResult<Self> {
        let window = crate::stitch::Window::from_name(window).map_err(value_error)?;
        let given = coarse.shape()[0];
        let t = match frames {
            None => given,
            Some(t) if t >= 1 && t as usize >= given && coarse_weight.is_some() => t as usize,
            Some(t) => return Err(PyValueError::new_err(format!("frames: expected the video's frame count, at least coarse's {given}, with coarse_weight (the joint alignment streams), got {t}"))),
        };
        let cs = [t, coarse.shape()[1], coarse.shape()[2]];
        let ps = [patch.0, patch.1, patch.2];
        if ps.iter().any(|&l| !(2..=1 << 12).contains(&l)) {
            return Err(PyValueError::new_err(format!("patch: expected three sizes in [2, 4096], got {ps:?}")));
        }
        let layout = crate::stitch::Layout::new([cs[0], cs[1], cs[2]], ps.map(|l| l as usize)).map_err(value_error)?;
        if coarse_weight.is_none() && temporal_weight != 0.0 {
            return Err(PyValueError::new_err("temporal_weight: the joint alignment's (give coarse_weight), expected 0 without it"));
        }
        let c = coarse.as_slice().map_err(|_| PyValueError::new_err("coarse: expected a C-contiguous array"))?.to_vec();
        let inner = py
            .detach(|| match coarse_weight {
                None => crate::stitch::Stitcher::new(layout, c, window).map(Alignment::Coarse),
                Some(mu) => crate::joint::JointStitcher::new(layout, c, mu, temporal_weight, window).map(Alignment::Joint),
            })
            .map_err(value_error)?;
        Ok(Self { inner: Some(inner), shape: layout.shape, patch: layout.patch })
    }

    fn add(&mut self, py: Python<'_>, patches: numpy::PyReadonlyArray4<'_, f32>, origins: PyReadonlyArray2<'_, i64>) -> PyResult<()> {
        let stitcher = self.inner.as_mut().ok_or_else(|| PyRuntimeError::new_err("Stitcher: already finished"))?;
        let ps = patches.shape();
        if ps[1..] != self.patch {
            return Err(PyValueError::new_err(format!("patches: expected (N, {}, {}, {}), got {ps:?}", self.patch[0], self.patch[1], self.patch[2])));
        }
        let n = ps[0];
        let origins: Vec<[usize; 3]> = rows::<i64, 3>("origins", &origins)?
            .iter()
            .map(|o| {
                if o.iter().any(|&v| v < 0) {
                    Err(PyValueError::new_err(format!("origins: expected non-negative (t, y, x), got {o:?}")))
                } else {
                    Ok(o.map(|v| v as usize))
                }
            })
            .collect::<PyResult<_>>()?;
        if origins.len() != n {
            return Err(PyValueError::new_err(format!("origins: expected one row per patch ({n}), got {}", origins.len())));
        }
        let p = patches.as_slice().map_err(|_| PyValueError::new_err("patches: expected a C-contiguous array"))?;
        parallel(py, || match stitcher {
            Alignment::Coarse(s) => s.add(p, &origins),
            Alignment::Joint(s) => s.add(p, &origins),
        })?
        .map_err(value_error)
    }

    /// The joint alignment's coarse depth of the next frames (n, H, W).
    fn push_coarse(&mut self, py: Python<'_>, coarse: PyReadonlyArray3<'_, f32>) -> PyResult<()> {
        let [_, h, w] = self.shape;
        if coarse.shape()[1..] != [h, w] {
            return Err(PyValueError::new_err(format!("coarse: expected frames of ({h}, {w}), got {:?}", coarse.shape())));
        }
        let c = coarse.as_slice().map_err(|_| PyValueError::new_err("coarse: expected a C-contiguous array"))?;
        match self.inner.as_mut().ok_or_else(|| PyRuntimeError::new_err("Stitcher: already finished"))? {
            Alignment::Coarse(_) => Err(PyValueError::new_err("coarse: the paper's alignment takes the whole coarse depth at once (it does not stream)")),
            Alignment::Joint(s) => parallel(py, || s.push_coarse(c))?.map_err(value_error),
        }
    }

    /// The joint alignment's frames stitched since the last `take` (n, H, W).
    fn take<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let [_, h, w] = self.shape;
        let video = match self.inner.as_mut().ok_or_else(|| PyRuntimeError::new_err("Stitcher: already finished"))? {
            Alignment::Coarse(_) => return Err(PyValueError::new_err("take: the paper's alignment gives its video at finish (it does not stream)")),
            Alignment::Joint(s) => s.take(),
        };
        let n = video.len() / (h * w);
        Ok(PyArray1::from_vec(py, video).reshape([n, h, w])?.into_any())
    }

    /// The frames not yet taken (all of them without `take`).
    fn finish<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let stitcher = self.inner.take().ok_or_else(|| PyRuntimeError::new_err("Stitcher: already finished"))?;
        let video = match stitcher {
            Alignment::Coarse(s) => s.finish(),
            Alignment::Joint(s) => s.finish().map_err(value_error)?,
        };
        let [_, h, w] = self.shape;
        let n = video.len() / (h * w);
        Ok(PyArray1::from_vec(py, video).reshape([n, h, w])?.into_any())
    }
}

/// Give every frame of a depth video (T, H, W) frame 0's GBR; returns a new array.
#[pyfunction]
fn temporal_align<'py>(py: Python<'py>, depth: PyReadonlyArray3<'py, f32>) -> PyResult<Bound<'py, PyAny>> {
    let s = depth.shape().to_vec();
    let mut data = depth.as_slice().map_err(|_| PyValueError::new_err("depth: expected a C-contiguous array"))?.to_vec();
    parallel(py, || crate::stitch::temporal_align(&mut data, [s[0], s[1], s[2]]))?.map_err(value_error)?;
    Ok(PyArray1::from_vec(py, data).reshape([s[0], s[1], s[2]])?.into_any())
}

/// Values at scattered points (column, row) spread over an (H, W) frame:
/// linear over the given triangles, the nearest point's value elsewhere.
#[pyfunction]
fn spread<'py>(py: Python<'py>, points: PyReadonlyArray2<'py, f64>, values: PyReadonlyArray1<'py, f64>, triangles: PyReadonlyArray2<'py, u32>,
               size: (i64, i64)) -> PyResult<Bound<'py, PyAny>> {
    let (h, w) = size;
    if h < 1 || w < 1 {
        return Err(PyValueError::new_err(format!("size: expected (H, W) >= 1, got ({h}, {w})")));
    }
    let (p, t) = (rows::<f64, 2>("points", &points)?, rows::<u32, 3>("triangles", &triangles)?);
    let v = values.as_slice().map_err(|_| PyValueError::new_err("values: expected a C-contiguous array"))?;
    let out = parallel(py, || crate::spread::spread(p, v, t, [h as usize, w as usize]))?.map_err(value_error)?;
    array2(py, out, h as usize, w as usize)
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
    m.add_function(wrap_pyfunction!(write_png16, m)?)?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(raycast_depth, m)?)?;
    m.add_function(wrap_pyfunction!(procedural_texture, m)?)?;
    m.add_function(wrap_pyfunction!(texture_families, m)?)?;
    m.add_function(wrap_pyfunction!(default_generator_config, m)?)?;
    m.add_function(wrap_pyfunction!(validate_generator_config, m)?)?;
    m.add_function(wrap_pyfunction!(generate_clips, m)?)?;
    m.add_function(wrap_pyfunction!(patch_layout, m)?)?;
    m.add_class::<PyStitcher>()?;
    m.add_function(wrap_pyfunction!(temporal_align, m)?)?;
    m.add_function(wrap_pyfunction!(spread, m)?)?;
    m.add("CAMERA_Z", crate::geometry::CAMERA_Z)?;
    m.add("FFT_PERIOD", synthesis::PERIOD)?;
    m.add("W_RADIUS", synthesis::W_RADIUS)?;
    m.add("SPECTRUM_CUTOFF", synthesis::SPECTRUM_CUTOFF)?;
    m.add("MAX_GRID", synthesis::MAX_GRID)?;
    m.add("MAX_FRAMES", synthesis::MAX_FRAMES)?;
    Ok(())
}
