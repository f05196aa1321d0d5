//! `gelrig.sim.Bench`: the simulated bench's camera for a contact given by hand — frames with
//! their exact marker centres and the contact's force at equilibrium, for building datasets
//! and testing perception code without a rig.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray3};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use gelrig::protocol::Overrides;
use gelrig::sim::{ContactCamera, ContactFrame, ContactPose, PlantSpec};

use crate::{frames, gelrig_err};

/// A sensor and an indenter, seen by the simulated bench's camera.
#[pyclass(module = "gelrig._gelrig")]
pub(crate) struct Bench {
    spec: PlantSpec,
    size: (u32, u32),
    seed: u64,
    pressing: ContactCamera,
    /// Built at the first shear or twist (the tangential tables cost more).
    tangential: Option<ContactCamera>,
    frames: u64,
}

/// A drawn frame as Python gets it: the image, the contact's wrench, the truth.
type Drawn<'py> = (
    Bound<'py, PyArray3<u8>>,
    Bound<'py, PyDict>,
    Bound<'py, PyDict>,
);

/// The shipped protocol whose sensor, gel and camera a bench of `sensor` uses.
fn protocol_of(sensor: &str) -> PyResult<&'static str> {
    match sensor {
        "box" => Ok("box-normal-flat"),
        "portable" => Ok("portable-normal"),
        other => Err(PyValueError::new_err(format!(
            "sensor `{other}`: give `box` (the thesis's box sensor) or `portable`"
        ))),
    }
}

fn frame_tuple<'py>(py: Python<'py>, f: ContactFrame, pose: &ContactPose) -> PyResult<Drawn<'py>> {
    let wrench = PyDict::new(py);
    wrench.set_item("fx_n", f.shear_n)?;
    wrench.set_item("fy_n", 0.0)?;
    wrench.set_item("fz_n", f.normal_force_n)?;
    wrench.set_item("tz_nmm", f.torque_nmm)?;
    let truth = PyDict::new(py);
    truth.set_item("depth_mm", pose.depth_mm)?;
    truth.set_item("shear_mm", pose.shear_mm)?;
    truth.set_item("twist_deg", pose.twist_deg)?;
    truth.set_item("contact_radius_mm", f.contact_radius_mm)?;
    truth.set_item("centre_mm", pose.centre_mm)?;
    truth.set_item("stick_fraction_shear", f.stick_fraction_shear)?;
    truth.set_item("stick_fraction_twist", f.stick_fraction_twist)?;
    // One channel loaded (or none): its stick fraction. Both: the model superposes the
    // two channels' tractions, and the combined contact's stick area is not known.
    let stick = match (pose.shear_mm != 0.0, pose.twist_deg != 0.0) {
        (true, true) => None,
        (false, true) => f.stick_fraction_twist,
        _ => f.stick_fraction_shear,
    };
    truth.set_item("stick_fraction", stick)?;
    let flat: Vec<f64> = f.markers_px.iter().flat_map(|p| [p[0], p[1]]).collect();
    let markers = Array2::from_shape_vec((f.markers_px.len(), 2), flat)
        .map_err(|e| gelrig_err(e.to_string()))?;
    truth.set_item("markers_px", markers.into_pyarray(py))?;
    let image = frames::to_numpy(py, f.width as usize, f.height as usize, f.rgb)?;
    Ok((image, wrench, truth))
}

#[pymethods]
impl Bench {
    /// `sensor`: `box` or `portable`; `indenter`: the protocol's `indenter:` as a dict of
    /// strings (`{"shape": "sphere", "diameter": "12.68 mm"}`; default: the shipped flat
    /// punch); `seed`: the camera noise; `width`, `height`: the camera (default: the rig's);
    /// `max_depth_mm`: the deepest press to draw (default: the shipped protocol's deepest
    /// step, 20 % of the layer).
    #[new]
    #[pyo3(signature = (sensor="box", indenter=None, seed=0, width=None, height=None, max_depth_mm=None))]
    fn new(
        py: Python<'_>,
        sensor: &str,
        indenter: Option<std::collections::BTreeMap<String, String>>,
        seed: u64,
        width: Option<u32>,
        height: Option<u32>,
        max_depth_mm: Option<f64>,
    ) -> PyResult<Self> {
        let (path, _) = gelrig::protocol::shipped::resolve(protocol_of(sensor)?.as_ref());
        let mut set = Vec::new();
        if let Some(ind) = indenter {
            let json = serde_json::to_string(&ind).map_err(gelrig_err)?;
            set.push(format!("indenter={json}"));
        }
        let overrides = Overrides {
            set,
            name: None,
            fidelity: None,
        };
        let built = py.detach(
            || -> Result<(PlantSpec, (u32, u32), ContactCamera), String> {
                let loaded = gelrig::protocol::load_with_overrides(
                    &path,
                    None,
                    &Default::default(),
                    &overrides,
                )
                .map_err(|d| {
                    d.iter()
                        .map(ToString::to_string)
                        .collect::<Vec<_>>()
                        .join("\n")
                })?;
                let mut spec = gelrig::sim::plant_spec(&loaded.protocol, &loaded.compiled)?;
                if let Some(d) = max_depth_mm {
                    let layer = spec.contact.layer.thickness_mm;
                    if !(d.is_finite() && d > 0.0 && d < layer) {
                        return Err(format!(
                            "max_depth_mm={d}: give a depth between 0 and the layer's {layer} mm"
                        ));
                    }
                    spec.max_depth_mm = d;
                }
                let cam = loaded.rig.camera.as_ref();
                let size = (
                    width.or(cam.map(|c| c.width)).unwrap_or(640),
                    height.or(cam.map(|c| c.height)).unwrap_or(480),
                );
                let pressing = ContactCamera::new(&spec, size.0, size.1)?;
                Ok((spec, size, pressing))
            },
        );
        let (spec, size, pressing) = built.map_err(gelrig_err)?;
        Ok(Self {
            spec,
            size,
            seed,
            pressing,
            tangential: None,
            frames: 0,
        })
    }

    /// The deepest indentation the bench draws, mm.
    #[getter]
    fn max_depth_mm(&self) -> f64 {
        self.spec.max_depth_mm
    }

    /// The camera's (width, height), px.
    #[getter]
    fn size(&self) -> (u32, u32) {
        self.size
    }

    /// The untouched gel: (frame, wrench, truth).
    fn reference<'py>(&mut self, py: Python<'py>) -> PyResult<Drawn<'py>> {
        let seq = self.next_seq();
        let f = self.pressing.at_rest(seq);
        frame_tuple(py, f, &ContactPose::default())
    }

    /// The gel pressed `depth_mm` deep, then the indenter moved `shear_mm` along the image's
    /// x and turned `twist_deg` about the normal (from the pressed state, as a stage does),
    /// the contact centred at (`x_mm`, `y_mm`) from the view's centre, at equilibrium:
    /// (frame, wrench, truth). The wrench is the contact's (its normal force once the gel
    /// has relaxed, the shear force and moment its partial slip sets); the truth holds the
    /// contact radius, the stick fractions and every marker's exact centre, px.
    #[pyo3(signature = (depth_mm, shear_mm=0.0, twist_deg=0.0, x_mm=0.0, y_mm=0.0))]
    fn press<'py>(
        &mut self,
        py: Python<'py>,
        depth_mm: f64,
        shear_mm: f64,
        twist_deg: f64,
        x_mm: f64,
        y_mm: f64,
    ) -> PyResult<Drawn<'py>> {
        let pose = ContactPose {
            depth_mm,
            shear_mm,
            twist_deg,
            centre_mm: (x_mm, y_mm),
        };
        if [depth_mm, shear_mm, twist_deg, x_mm, y_mm]
            .iter()
            .any(|v| !v.is_finite())
        {
            return Err(PyValueError::new_err(format!(
                "press({depth_mm}, shear_mm={shear_mm}, twist_deg={twist_deg}, x_mm={x_mm}, \
                 y_mm={y_mm}): give finite numbers"
            )));
        }
        let seq = self.next_seq();
        let tangential = shear_mm != 0.0 || twist_deg != 0.0;
        if tangential && self.tangential.is_none() {
            let (spec, (w, h)) = (&self.spec, self.size);
            let cam = py.detach(|| ContactCamera::with_shear_and_twist(spec, w, h));
            self.tangential = Some(cam.map_err(gelrig_err)?);
        }
        let camera = match (&mut self.tangential, tangential) {
            (Some(c), true) => c,
            _ => &mut self.pressing,
        };
        let f = py
            .detach(|| camera.frame(&pose, seq))
            .map_err(PyValueError::new_err)?;
        frame_tuple(py, f, &pose)
    }
}

impl Bench {
    fn next_seq(&mut self) -> u64 {
        self.frames += 1;
        self.seed.wrapping_mul(1_000_003).wrapping_add(self.frames)
    }
}
