//! `gelrig.Shape`: a GelSight calibrated as a shape sensor (`gelrig shape calibrate`'s
//! shape file) reading height maps from numpy frames.

use std::path::PathBuf;

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray3};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use gelrig::shape::{Depth, ModelKind, Rgb, ShapeFile};

use crate::frames;
use crate::gelrig_err;

/// A shape sensor: its file, and the reader for the background given.
#[pyclass(module = "gelrig._gelrig")]
pub(crate) struct Shape {
    file: ShapeFile,
    path: PathBuf,
    depth: Depth,
    frame: frames::Rgb,
}

fn model_kind(name: Option<&str>) -> PyResult<Option<ModelKind>> {
    match name {
        None => Ok(None),
        Some("local-linear") => Ok(Some(ModelKind::LocalLinear)),
        Some("lut") => Ok(Some(ModelKind::Lut)),
        Some(other) => Err(gelrig_err(format!(
            "model {other:?}: give \"local-linear\" or \"lut\" (or None for the file's chosen one)"
        ))),
    }
}

#[pymethods]
impl Shape {
    /// Reads the shape file at `path` and prepares it for frames like `background` (the
    /// unpressed gel, same session, uint8 H×W×3); `model` overrides the file's choice.
    #[staticmethod]
    #[pyo3(signature = (path, background, model=None))]
    fn load(
        path: PathBuf,
        background: PyReadonlyArray3<'_, u8>,
        model: Option<&str>,
    ) -> PyResult<Self> {
        let file = ShapeFile::read(&path).map_err(gelrig_err)?;
        let bg = frames::Rgb::from_numpy(&background, "background")?;
        if (bg.width, bg.height) != (file.width_px, file.height_px) {
            return Err(gelrig_err(format!(
                "background: {}×{} px; {} was calibrated on {}×{} px frames: use the camera \
                 setting it was calibrated at",
                bg.width,
                bg.height,
                path.display(),
                file.width_px,
                file.height_px
            )));
        }
        let map = file
            .model(model_kind(model)?)
            .prepare(bg.width, bg.height)
            .ok_or_else(|| {
                gelrig_err("the shape file's model holds too little: calibrate again")
            })?;
        let view = Rgb::new(bg.width, bg.height, &bg.bytes).map_err(gelrig_err)?;
        let depth = Depth::new(map, view, file.mm_per_px).map_err(gelrig_err)?;
        Ok(Self {
            file,
            path,
            depth,
            frame: bg,
        })
    }

    /// The shape file.
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// Image scale, mm per px.
    #[getter]
    fn mm_per_px(&self) -> f64 {
        self.file.mm_per_px
    }

    /// Each model's figures on presses left out of its fit, and its cost (as in the file).
    #[getter]
    fn figures<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let text = serde_json::to_string(&self.file.figures).map_err(gelrig_err)?;
        py.import("json")?.call_method1("loads", (text,))
    }

    /// The height map of `frame` (uint8 H×W×3): float32 H×W, mm, positive out of the gel (a
    /// press reads negative), 0 on the untouched gel. The GIL is released while it is read.
    fn height<'py>(
        &mut self,
        py: Python<'py>,
        frame: PyReadonlyArray3<'_, u8>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        self.frame.copy_from(&frame, "frame")?;
        let (w, h) = (self.frame.width, self.frame.height);
        let (depth, bytes) = (&mut self.depth, &self.frame.bytes);
        let height = py
            .detach(|| -> Result<Vec<f32>, String> {
                let view = Rgb::new(w, h, bytes).map_err(|e| e.to_string())?;
                depth
                    .height(view)
                    .map(<[f32]>::to_vec)
                    .map_err(|e| e.to_string())
            })
            .map_err(gelrig_err)?;
        let a = Array2::from_shape_vec((h, w), height).map_err(gelrig_err)?;
        Ok(a.into_pyarray(py))
    }

    /// The last frame's contact from its height: `max_depth_mm`, `contact_area_mm2` (deeper
    /// than 0.03 mm), `centroid_px` (x, y; None without contact), `volume_mm3`.
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.depth.stats();
        let d = PyDict::new(py);
        d.set_item("max_depth_mm", s.max_depth_mm)?;
        d.set_item("contact_area_mm2", s.contact_area_mm2)?;
        d.set_item(
            "centroid_px",
            s.centroid_px[0]
                .is_finite()
                .then_some((s.centroid_px[0], s.centroid_px[1])),
        )?;
        d.set_item("volume_mm3", s.volume_mm3)?;
        Ok(d)
    }
}
