//! Array arguments whose errors name what was expected: numpy's own
//! conversion says only "cannot be converted to 'PyArray<T, D>'".
use numpy::{Element, PyReadonlyArray, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;

/// A read-only array argument of element `T` and dimension `D`.
pub struct Arr<'py, T: Element, D: numpy::ndarray::Dimension>(pub PyReadonlyArray<'py, T, D>);

impl<'py, T: Element, D: numpy::ndarray::Dimension> std::ops::Deref for Arr<'py, T, D> {
    type Target = PyReadonlyArray<'py, T, D>;
    fn deref(&self) -> &Self::Target {
        &self.0
    }
}

impl<'py, T: Element, D: numpy::ndarray::Dimension> FromPyObject<'py> for Arr<'py, T, D> {
    fn extract_bound(ob: &Bound<'py, PyAny>) -> PyResult<Self> {
        if let Ok(a) = ob.extract::<PyReadonlyArray<'py, T, D>>() {
            return Ok(Arr(a));
        }
        let want = numpy::dtype::<T>(ob.py());
        let dims = D::NDIM.map_or("any number of".to_owned(), |n| n.to_string());
        let got = match ob.downcast::<PyUntypedArray>() {
            Ok(a) => format!("a {} array of shape {:?}", a.dtype(), a.shape()),
            Err(_) => format!("a {}", ob.get_type().name()?),
        };
        Err(PyTypeError::new_err(format!(
            "expected a numpy {want} array with {dims} dimensions (convert with .astype(np.{want})), got {got}"
        )))
    }
}

pub type Arr1<'py, T> = Arr<'py, T, numpy::ndarray::Ix1>;
pub type Arr2<'py, T> = Arr<'py, T, numpy::ndarray::Ix2>;
pub type Arr3<'py, T> = Arr<'py, T, numpy::ndarray::Ix3>;
pub type Arr4<'py, T> = Arr<'py, T, numpy::ndarray::Ix4>;
