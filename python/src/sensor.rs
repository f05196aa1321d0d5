//! `gelrig.ForceSensor`: a calibrated GelSight (a sensor file from `gelrig calibrate`) read
//! frame by frame from numpy frames, keeping the gel's memory across successive frames as a
//! run's live reading does.

use std::path::PathBuf;

use numpy::PyReadonlyArray3;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use gelrig::force::{LiveReader, SensorFile};
use gelrig::track::{ContactParams, Method, Pipeline, TrackParams};

use crate::frames::Rgb;
use crate::gelrig_err;

/// Frames apart when the caller gives no times: the simulated camera's 25 Hz.
const DEFAULT_PERIOD_NS: u64 = 40_000_000;

/// A calibrated GelSight read from frames.
#[pyclass(module = "gelrig._gelrig")]
pub(crate) struct ForceSensor {
    file: SensorFile,
    path: PathBuf,
    /// The tracking of the current sequence and its reader, from its reference frame.
    sequence: Option<(Pipeline, LiveReader, (usize, usize))>,
    frames: u64,
}

#[pymethods]
impl ForceSensor {
    /// Reads the sensor file at `path`.
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        let file = SensorFile::read(&path).map_err(gelrig_err)?;
        Ok(Self {
            file,
            path,
            sequence: None,
            frames: 0,
        })
    }

    /// The sensor file.
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// Starts a sequence at `reference` (the untouched gel); the gel's memory starts afresh.
    fn reset(&mut self, py: Python<'_>, reference: PyReadonlyArray3<'_, u8>) -> PyResult<()> {
        let rgb = Rgb::from_numpy(&reference, "reference")?;
        let made = py.detach(|| -> Result<Pipeline, String> {
            let view = rgb.view().map_err(|e| e.to_string())?;
            let mut p = Pipeline::new(view, &TrackParams::default(), Method::Centroid)
                .map_err(|e| e.to_string())?;
            p.enable_contact(view, ContactParams::default())
                .map_err(|e| e.to_string())?;
            Ok(p)
        });
        let pipeline = made.map_err(gelrig_err)?;
        self.sequence = Some((
            pipeline,
            LiveReader::new(&self.file),
            (rgb.width, rgb.height),
        ));
        self.frames = 0;
        Ok(())
    }

    /// Fx, Fy, Fz (N), Tz (N·mm) of `frame` and their standard uncertainties (`fz_sd_n`, …),
    /// with why the frame lies outside the calibration (`outside`, empty when inside). The
    /// first frame of a sequence (or the first after `reset`) is its reference: the gel
    /// untouched. `t_s`: the frame's time, s (default: 25 frames a second).
    #[pyo3(signature = (frame, t_s=None))]
    fn read<'py>(
        &mut self,
        py: Python<'py>,
        frame: PyReadonlyArray3<'_, u8>,
        t_s: Option<f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        if self.sequence.is_none() {
            self.reset(py, frame.clone())?;
        }
        let rgb = Rgb::from_numpy(&frame, "frame")?;
        let t_ns = match t_s {
            Some(t) if t.is_finite() && t >= 0.0 => (t * 1e9) as u64,
            Some(t) => return Err(PyValueError::new_err(format!("t_s={t}: give a time ≥ 0 s"))),
            None => self.frames * DEFAULT_PERIOD_NS,
        };
        let Some((pipeline, reader, size)) = self.sequence.as_mut() else {
            return Err(gelrig_err("no reference frame"));
        };
        if (rgb.width, rgb.height) != *size {
            return Err(PyValueError::new_err(format!(
                "frame of {}×{} px; the reference is {}×{} px",
                rgb.width, rgb.height, size.0, size.1
            )));
        }
        let wrench = py
            .detach(|| -> Result<_, String> {
                let view = rgb.view().map_err(|e| e.to_string())?;
                pipeline.track(view).map_err(|e| e.to_string())?;
                reader.read(pipeline, t_ns).map_err(|e| e.to_string())
            })
            .map_err(gelrig_err)?;
        self.frames += 1;
        let d = PyDict::new(py);
        let names = [
            ("fx_n", "fx_sd_n"),
            ("fy_n", "fy_sd_n"),
            ("fz_n", "fz_sd_n"),
            ("tz_nmm", "tz_sd_nmm"),
        ];
        for (k, (v, sd)) in names.iter().enumerate() {
            d.set_item(*v, wrench.value.get(k).copied())?;
            d.set_item(*sd, wrench.sd.get(k).copied())?;
        }
        d.set_item("outside", wrench.judgement.reasons())?;
        Ok(d)
    }
}
