//! `gelrig.Tracker`: the marker tracker on numpy frames — the same pipeline, parameters and
//! numbers as `gelrig track` on the same pixels (centroid detection, identity, optional
//! Lucas–Kanade, the contact region).

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use gelrig::track::{ContactParams, MarkerState, Method, Pipeline, TrackParams};

use crate::frames::{self, Rgb};
use crate::gelrig_err;

/// Follows every marker of a reference frame through the frames it is given.
#[pyclass(module = "gelrig._gelrig")]
pub(crate) struct Tracker {
    pipeline: Pipeline,
    size: (usize, usize),
    mm_per_px: Option<f64>,
    /// A strided frame's pixels, copied out of numpy into a buffer kept between calls.
    frame: Rgb,
}

/// One tracked frame.
#[pyclass(module = "gelrig._gelrig", frozen)]
pub(crate) struct TrackResult {
    xy: Vec<[f64; 2]>,
    dxy: Vec<[f64; 2]>,
    state: Vec<&'static str>,
    confidence: Vec<f64>,
    /// Area px², centroid px, equivalent radius px.
    contact: Option<(f64, [f64; 2], f64)>,
    mm_per_px: Option<f64>,
}

fn state_name(s: MarkerState) -> &'static str {
    s.as_str()
}

fn points<'py>(py: Python<'py>, p: &[[f64; 2]]) -> Bound<'py, PyArray2<f64>> {
    let flat: Vec<f64> = p.iter().flat_map(|v| [v[0], v[1]]).collect();
    // Shape (n, 2) of n·2 values: always consistent.
    Array2::from_shape_vec((p.len(), 2), flat)
        .unwrap_or_else(|_| Array2::zeros((0, 2)))
        .into_pyarray(py)
}

#[pymethods]
impl Tracker {
    /// `reference`: the untouched gel, a `uint8` array (height, width, 3). `method`:
    /// `centroid`, `lk` or `centroid+lk`. `mm_per_px`: the image scale, for the contact's
    /// radius in mm. `contact`: also find the contact region of each frame.
    #[new]
    #[pyo3(signature = (reference, method="centroid", mm_per_px=None, contact=true))]
    fn new(
        py: Python<'_>,
        reference: PyReadonlyArray3<'_, u8>,
        method: &str,
        mm_per_px: Option<f64>,
        contact: bool,
    ) -> PyResult<Self> {
        let method: Method = method.parse().map_err(PyValueError::new_err)?;
        if let Some(s) = mm_per_px
            && !(s.is_finite() && s > 0.0)
        {
            return Err(PyValueError::new_err(format!(
                "mm_per_px={s}: give the image scale in mm per pixel (> 0), or None"
            )));
        }
        let rgb = Rgb::from_numpy(&reference, "reference")?;
        let pipeline = py.detach(|| -> Result<Pipeline, String> {
            let view = rgb.view().map_err(|e| e.to_string())?;
            let mut p =
                Pipeline::new(view, &TrackParams::default(), method).map_err(|e| e.to_string())?;
            if contact {
                p.enable_contact(view, ContactParams::default())
                    .map_err(|e| e.to_string())?;
            }
            Ok(p)
        });
        Ok(Self {
            pipeline: pipeline.map_err(gelrig_err)?,
            size: (rgb.width, rgb.height),
            mm_per_px,
            frame: rgb,
        })
    }

    /// The number of reference markers (the ids are 0 … n−1).
    fn __len__(&self) -> usize {
        self.pipeline.tracker().len()
    }

    /// The reference markers' positions, px (n×2).
    #[getter]
    fn reference_xy<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        points(py, self.pipeline.tracker().reference_px())
    }

    /// Tracks `frame` (same size as the reference) and returns where every marker is.
    ///
    /// A C-contiguous frame (what a camera, `cv2` or `np.asarray` hands over) is read in
    /// place with the GIL released, as OpenCV-Python reads its arrays: another thread must
    /// not write into it meanwhile. Any other layout (a crop, a channel flip, Fortran order)
    /// is copied first, in row-major order.
    fn track(&mut self, py: Python<'_>, frame: PyReadonlyArray3<'_, u8>) -> PyResult<TrackResult> {
        let shape = frame.shape();
        frames::check_rgb(shape, "frame")?;
        if (shape[1], shape[0]) != self.size {
            return Err(PyValueError::new_err(format!(
                "frame of shape {shape:?}; the reference is ({}, {}, 3): track uint8 RGB frames \
                 of the same camera",
                self.size.1, self.size.0
            )));
        }
        let (width, height) = self.size;
        let pipeline = &mut self.pipeline;
        let bytes: &[u8] = match frames::c_order(&frame) {
            Some(s) => s,
            None => {
                self.frame.copy_from(&frame, "frame")?;
                &self.frame.bytes
            }
        };
        py.detach(|| -> Result<(), String> {
            let view =
                gelrig::track::RgbView::new(width, height, bytes).map_err(|e| e.to_string())?;
            pipeline.track(view).map_err(|e| e.to_string())
        })
        .map_err(gelrig_err)?;
        let t = self.pipeline.tracker();
        Ok(TrackResult {
            xy: t.positions_px().to_vec(),
            dxy: (0..t.len()).map(|k| t.displacement_px(k)).collect(),
            state: t.states().iter().map(|s| state_name(*s)).collect(),
            confidence: t.confidences().to_vec(),
            contact: self
                .pipeline
                .contact()
                .map(|c| (c.area_px2, c.centroid_px, c.radius_px)),
            mm_per_px: self.mm_per_px,
        })
    }
}

#[pymethods]
impl TrackResult {
    /// Marker ids (0 … n−1, fixed for the sequence).
    #[getter]
    fn ids<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u32>> {
        (0..self.xy.len() as u32)
            .collect::<Vec<_>>()
            .into_pyarray(py)
    }

    /// Positions, px (n×2, pixel (i, j) centred at (i, j)).
    #[getter]
    fn xy<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        points(py, &self.xy)
    }

    /// Displacements from the reference, px (n×2).
    #[getter]
    fn dxy<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        points(py, &self.dxy)
    }

    /// Each marker's state: tracked, border, merged, predicted, out_of_view, ambiguous, lost.
    #[getter]
    fn state(&self) -> Vec<&'static str> {
        self.state.clone()
    }

    /// Confidence in each identity, 0–1 (0 when not measured).
    #[getter]
    fn confidence<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.confidence.clone().into_pyarray(py)
    }

    /// The contact region (`area_px2`, `cx_px`, `cy_px`, `radius_px`, `radius_mm` — None
    /// without an image scale), or None without contact.
    #[getter]
    fn contact<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some((area, c, r)) = self.contact else {
            return Ok(None);
        };
        let d = PyDict::new(py);
        d.set_item("area_px2", area)?;
        d.set_item("cx_px", c[0])?;
        d.set_item("cy_px", c[1])?;
        d.set_item("radius_px", r)?;
        d.set_item("radius_mm", self.mm_per_px.map(|s| r * s))?;
        Ok(Some(d))
    }

    fn __len__(&self) -> usize {
        self.xy.len()
    }
}
