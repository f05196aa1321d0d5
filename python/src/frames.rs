//! Frames at the boundary: numpy `uint8` arrays of H×W×3 in, RGB bytes for the tracker; RGB
//! bytes out as numpy arrays.

use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray3, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// An RGB frame copied out of a numpy array: its width, height and bytes.
pub(crate) struct Rgb {
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) bytes: Vec<u8>,
}

impl Rgb {
    /// The frame in `array`, which must be `uint8` of shape (height, width, 3); a copy, so
    /// the GIL can be released while it is tracked.
    pub(crate) fn from_numpy(array: &PyReadonlyArray3<'_, u8>, what: &str) -> PyResult<Self> {
        let mut rgb = Self {
            width: 0,
            height: 0,
            bytes: Vec::new(),
        };
        rgb.copy_from(array, what)?;
        Ok(rgb)
    }

    /// Copies `array` into this frame's buffer, reusing its allocation: a tracker called on
    /// every camera frame then allocates (and faults in) no new memory per frame.
    pub(crate) fn copy_from(
        &mut self,
        array: &PyReadonlyArray3<'_, u8>,
        what: &str,
    ) -> PyResult<()> {
        let shape = array.shape();
        check_rgb(shape, what)?;
        self.bytes.clear();
        match c_order(array) {
            Some(s) => self.bytes.extend_from_slice(s),
            // A strided view (a crop, a BGR→RGB flip) or a Fortran-ordered array (MATLAB
            // data): copied in row-major order.
            None => self.bytes.extend(array.as_array().iter().copied()),
        }
        self.width = shape[1];
        self.height = shape[0];
        Ok(())
    }

    /// The tracker's view of these bytes.
    pub(crate) fn view(&self) -> PyResult<gelrig::track::RgbView<'_>> {
        gelrig::track::RgbView::new(self.width, self.height, &self.bytes)
            .map_err(|e| PyValueError::new_err(e.to_string()))
    }
}

/// The array's bytes when they are in row-major (C) order, as the tracker reads them; `None`
/// for any other layout (numpy's `as_slice` also accepts Fortran order, whose bytes are the
/// same pixels in another order).
pub(crate) fn c_order<'a>(array: &'a PyReadonlyArray3<'_, u8>) -> Option<&'a [u8]> {
    if array.is_c_contiguous() {
        array.as_slice().ok()
    } else {
        None
    }
}

/// An array of `shape` is an RGB frame (height, width, 3), or the error says how to make one.
pub(crate) fn check_rgb(shape: &[usize], what: &str) -> PyResult<()> {
    if shape[2] != 3 {
        return Err(PyValueError::new_err(format!(
            "{what}: an array of shape {shape:?}; give an RGB frame of shape (height, width, 3), \
             dtype uint8 (a grey image: np.repeat(img[..., None], 3, axis=2))"
        )));
    }
    Ok(())
}

/// `rgb` (row-major, 3 bytes a pixel) as a numpy array of shape (height, width, 3).
pub(crate) fn to_numpy<'py>(
    py: Python<'py>,
    width: usize,
    height: usize,
    rgb: Vec<u8>,
) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let a = Array3::from_shape_vec((height, width, 3), rgb)
        .map_err(|e| PyValueError::new_err(format!("a frame of {width}×{height}: {e}")))?;
    Ok(a.into_pyarray(py))
}
