//! `Model`: a robot model built from URDF (immutable), its coordinates' names, and the library's
//! algorithms as methods. Each method takes real numbers (float64 arrays read in place for one
//! state and copied for N, other float and integer arrays and sequences of numbers converted;
//! masked arrays refused): 1-D for one state, 2-D for N states (a row each, results stacked).
//! Conventions are the library's: SI units, `q` and `v` in the order of `v_names`, a floating
//! base's `q = [x y z qx qy qz qw]` and `v = [linear; angular]` in the base frame; matrices
//! row-major (numpy's C order).

use crate::batch::{run, run_blocks, Workspaces};
use crate::errors::{error, from_library};
use nalgebra::DMatrix;
use numpy::{PyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyOSError;
use pyo3::prelude::*;
use spatial_dynamics_core::algorithms::method_choice::AUTO_TOLERANCE;
use spatial_dynamics_core::algorithms::{
    aba_derivatives, center_of_mass_jacobian, choose_method, crba, find_frame, forward_dynamics,
    frame_jacobian, frame_placement, gravity, rnea, rnea_derivatives, rnea_rows,
    ForwardDynamicsMethod, ReferenceFrame,
};
use spatial_dynamics_core::{urdf, DynamicsError, Externals, ModelError, ModelOptions, Workspace};
use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::time::Duration;

type Array<'py> = Bound<'py, PyArrayDyn<f64>>;

/// The largest URDF file `Model.from_urdf` reads: the library's limit (64 MiB), far above any
/// robot description (a full humanoid's is under 1 MiB), so that a huge file is refused before
/// it is read.
pub const MAX_URDF_BYTES: u64 = spatial_dynamics_core::urdf::MAX_FILE_BYTES;

/// A robot model built from URDF, with the URDF text and options it was built from (for
/// pickling) and the workspaces of its calls.
#[pyclass(frozen, module = "spatial_dynamics")]
pub struct Model {
    model: spatial_dynamics_core::Model,
    /// Workspaces between calls: one per thread a call runs on, kept for the next.
    workspaces: Workspaces,
    /// The method `method=None` uses: the library's `auto` choice for this model.
    method: ForwardDynamicsMethod,
    /// The URDF text the model was built from.
    xml: String,
    floating_base: bool,
    ignore_mimic: bool,
}

impl Model {
    /// The model of URDF text `xml` with the options of `from_urdf_string`, or the library's
    /// error.
    fn build(xml: String, floating_base: bool, ignore_mimic: bool) -> Result<Self, ModelError> {
        let options = ModelOptions {
            floating_base,
            ignore_mimic,
            ..ModelOptions::default()
        };
        let model = urdf::model_from_str(&xml, &options)?;
        // `aba` when no method runs on the model (a singular mass matrix): forward dynamics
        // then says why.
        let method = choose_method(&model, AUTO_TOLERANCE, Duration::ZERO)
            .map_or(ForwardDynamicsMethod::Aba, |choice| choice.method);
        Ok(Model {
            workspaces: Workspaces::new(&model),
            model,
            method,
            xml,
            floating_base,
            ignore_mimic,
        })
    }

    /// [`run`] with this model and its workspaces.
    fn run<'py, const I: usize, const O: usize, K>(
        &self,
        py: Python<'py>,
        inputs: [(&str, &Bound<'py, PyAny>, usize); I],
        outputs: [&[usize]; O],
        kernel: K,
    ) -> PyResult<[Array<'py>; O]>
    where
        K: Fn(&mut Workspace, [&[f64]; I], [&mut [f64]; O]) -> Result<(), DynamicsError> + Sync,
    {
        run(py, &self.model, &self.workspaces, inputs, outputs, kernel)
    }

    /// Three `(nv, nv)` matrices of the state `(q, v, x)` (`x` as its name and value; `nv`
    /// values each), `(N, nv, nv)` for N states: `kernel` gives them, they are written
    /// row-major.
    fn derivatives<'py, K>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        v: &Bound<'py, PyAny>,
        (x_name, x): (&str, &Bound<'py, PyAny>),
        kernel: K,
    ) -> PyResult<(Array<'py>, Array<'py>, Array<'py>)>
    where
        K: for<'w> Fn(
                &'w mut Workspace,
                &[f64],
                &[f64],
                &[f64],
            ) -> Result<[&'w DMatrix<f64>; 3], DynamicsError>
            + Sync,
    {
        let (nq, nv) = (self.model.nq(), self.model.nv());
        let [d0, d1, d2] = self.run(
            py,
            [("q", q, nq), ("v", v, nv), (x_name, x, nv)],
            [&[nv, nv]; 3],
            |ws, [q, v, x], outs| {
                for (out, matrix) in outs.into_iter().zip(kernel(ws, q, v, x)?) {
                    row_major(out, matrix);
                }
                Ok(())
            },
        )?;
        Ok((d0, d1, d2))
    }
}

/// The text of the URDF file at `path`: a regular file of at most [`MAX_URDF_BYTES`], UTF-8.
/// A file that cannot be opened or read is the `OSError` subclass of its errno
/// (`FileNotFoundError`, `PermissionError`, `IsADirectoryError`, ...) with the path as its
/// filename; a file of another kind (a device, a FIFO), a bigger one or one that is not UTF-8
/// is a `DynamicsError` naming the path. The file is read with the GIL released.
fn read_urdf(py: Python<'_>, path: &Path) -> PyResult<String> {
    let shown = path.display().to_string();
    let os_error = |e: std::io::Error| os_error(py, e, &shown);
    // The path's kind and size are checked before it is opened (opening a FIFO waits for a
    // writer), and the opened file's again (the path may have changed in between).
    let check = |metadata: std::fs::Metadata| -> PyResult<()> {
        if metadata.is_dir() {
            let eisdir = py.import("errno")?.getattr("EISDIR")?.extract::<i32>()?;
            return Err(os_error(std::io::Error::from_raw_os_error(eisdir)));
        }
        if !metadata.is_file() {
            return Err(error(format!(
                "{shown} is not a regular file: a URDF is read from one"
            )));
        }
        if metadata.len() > MAX_URDF_BYTES {
            return Err(too_big(&shown));
        }
        Ok(())
    };
    check(std::fs::metadata(path).map_err(os_error)?)?;
    let file = File::open(path).map_err(os_error)?;
    check(file.metadata().map_err(os_error)?)?;
    // At most one byte over the limit is read, should the file grow meanwhile.
    let bytes = py
        .detach(|| {
            let mut bytes = Vec::new();
            file.take(MAX_URDF_BYTES + 1)
                .read_to_end(&mut bytes)
                .map(|_| bytes)
        })
        .map_err(os_error)?;
    if bytes.len() as u64 > MAX_URDF_BYTES {
        return Err(too_big(&shown));
    }
    String::from_utf8(bytes).map_err(|e| error(format!("{shown} is not UTF-8 text: {e}")))
}

/// The `DynamicsError` of a URDF file over [`MAX_URDF_BYTES`].
fn too_big(shown: &str) -> PyErr {
    error(format!(
        "{shown} is larger than {} MiB, the most a URDF file may take",
        MAX_URDF_BYTES >> 20
    ))
}

/// `e`, an error reading `filename`, as Python's `OSError(errno, strerror, filename)`, which is
/// the subclass of the errno (`FileNotFoundError` for `ENOENT`, ...); an error without an errno
/// is an `OSError` with Rust's message.
fn os_error(py: Python<'_>, e: std::io::Error, filename: &str) -> PyErr {
    match e.raw_os_error() {
        Some(errno) => {
            let strerror = py
                .import("os")
                .and_then(|os| os.getattr("strerror")?.call1((errno,))?.extract::<String>())
                .unwrap_or_else(|_| e.to_string());
            PyOSError::new_err((errno, strerror, filename.to_string()))
        }
        None => PyOSError::new_err(format!("{filename}: {e}")),
    }
}

/// `matrix` into `out`, row-major.
fn row_major(out: &mut [f64], matrix: &DMatrix<f64>) {
    let ncols = matrix.ncols();
    for (r, row) in out.chunks_exact_mut(ncols.max(1)).enumerate() {
        for (c, x) in row.iter_mut().enumerate() {
            *x = matrix[(r, c)];
        }
    }
}

fn reference_frame(reference: &str) -> PyResult<ReferenceFrame> {
    match reference {
        "world" => Ok(ReferenceFrame::World),
        "local" => Ok(ReferenceFrame::Local),
        "local_world_aligned" => Ok(ReferenceFrame::LocalWorldAligned),
        _ => Err(error(format!(
            "reference '{reference}' is none of 'world', 'local', 'local_world_aligned'"
        ))),
    }
}

#[pymethods]
impl Model {
    /// The model of the URDF file at `path`, a regular file of at most 64 MiB of UTF-8 text.
    /// A file that cannot be read raises the `OSError` subclass of its cause
    /// (`FileNotFoundError`, `PermissionError`, `IsADirectoryError`); another kind of file (a
    /// device, a FIFO), a bigger one or a URDF the library refuses raises `DynamicsError`, its
    /// message starting with the path.
    #[staticmethod]
    #[pyo3(signature = (path, floating_base=false, ignore_mimic=false))]
    fn from_urdf(
        py: Python<'_>,
        path: PathBuf,
        floating_base: bool,
        ignore_mimic: bool,
    ) -> PyResult<Self> {
        let xml = read_urdf(py, &path)?;
        py.detach(|| Model::build(xml, floating_base, ignore_mimic))
            .map_err(|e| error(format!("{}: {e}", path.display())))
    }

    /// The model of the URDF text `xml`.
    #[staticmethod]
    #[pyo3(signature = (xml, floating_base=false, ignore_mimic=false))]
    fn from_urdf_string(
        py: Python<'_>,
        xml: String,
        floating_base: bool,
        ignore_mimic: bool,
    ) -> PyResult<Self> {
        py.detach(|| Model::build(xml, floating_base, ignore_mimic))
            .map_err(from_library)
    }

    /// Pickling: `Model.from_urdf_string` with the URDF text and options the model was built
    /// from (a model read from a file does not need the file to be unpickled).
    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, (String, bool, bool))> {
        let build = py.get_type::<Model>().getattr("from_urdf_string")?;
        Ok((
            build,
            (self.xml.clone(), self.floating_base, self.ignore_mimic),
        ))
    }

    /// The model itself: a `Model` is immutable (its workspaces are scratch that no result
    /// depends on), so a copy would behave the same.
    fn __copy__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    /// The model itself, as `__copy__`: a `Model` is immutable. `memo` (named as in
    /// `copy.deepcopy`'s protocol and the stubs, so it can be passed by keyword) is not needed.
    #[allow(unused_variables)]
    fn __deepcopy__(slf: Py<Self>, memo: &Bound<'_, PyAny>) -> Py<Self> {
        slf
    }

    /// Position coordinates.
    #[getter]
    fn nq(&self) -> usize {
        self.model.nq()
    }

    /// Velocity coordinates.
    #[getter]
    fn nv(&self) -> usize {
        self.model.nv()
    }

    /// The name of each velocity coordinate, in `v` order.
    #[getter]
    fn v_names(&self) -> Vec<String> {
        (0..self.model.nv()).map(|i| self.model.v_name(i)).collect()
    }

    /// The URDF links, frames of `frame_placement` and `frame_jacobian`.
    #[getter]
    fn link_names(&self) -> Vec<String> {
        self.model.links().iter().map(|l| l.name.clone()).collect()
    }

    /// The method `forward_dynamics(method=None)` uses for this model: "aba", "crba" or
    /// "rnea_columns".
    #[getter]
    fn forward_dynamics_method(&self) -> &'static str {
        self.method.name()
    }

    fn __repr__(&self) -> String {
        format!(
            "Model('{}', nq={}, nv={})",
            self.model.name(),
            self.model.nq(),
            self.model.nv()
        )
    }

    /// Inverse dynamics `tau = M(q) a + C(q, v) + g(q)` (gravity, base at rest, no external
    /// forces): `(nv,)`, or `(N, nv)`. N states go to the library's `rnea_rows` a block of
    /// rows at a time (several states in the lanes of each instruction), one state to `rnea`:
    /// the same bits either way.
    fn rnea<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        v: &Bound<'py, PyAny>,
        a: &Bound<'py, PyAny>,
    ) -> PyResult<Array<'py>> {
        let (m, nq, nv) = (&self.model, self.model.nq(), self.model.nv());
        let [tau] = run_blocks(
            py,
            m,
            &self.workspaces,
            [("q", q, nq), ("v", v, nv), ("a", a, nv)],
            [&[nv]],
            &|ws: &mut Workspace, [q, v, a]: [&[f64]; 3], [tau]: [&mut [f64]; 1]| {
                tau.copy_from_slice(rnea(m, ws, q, v, a)?);
                Ok(())
            },
            |ws, _rows, [q, v, a], [tau]| rnea_rows(m, ws, q, v, a, tau),
        )?;
        Ok(tau)
    }

    /// Generalized gravity `g(q)`, the efforts that hold the robot still at `q`: `(nv,)`, or
    /// `(N, nv)`.
    fn gravity<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Array<'py>> {
        let (m, nq, nv) = (&self.model, self.model.nq(), self.model.nv());
        let [g] = self.run(py, [("q", q, nq)], [&[nv]], |ws, [q], [g]| {
            g.copy_from_slice(gravity(m, ws, q)?);
            Ok(())
        })?;
        Ok(g)
    }

    /// Forward dynamics `qdd = M(q)⁻¹ (tau − C(q, v) − g(q))` by `method` ("aba", "crba",
    /// "rnea_columns"; `None`: `forward_dynamics_method`): `(nv,)`, or `(N, nv)`.
    #[pyo3(signature = (q, v, tau, method=None))]
    fn forward_dynamics<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        v: &Bound<'py, PyAny>,
        tau: &Bound<'py, PyAny>,
        method: Option<&str>,
    ) -> PyResult<Array<'py>> {
        let method = match method {
            None => self.method,
            Some(name) => name.parse().map_err(error)?,
        };
        let (m, nq, nv) = (&self.model, self.model.nq(), self.model.nv());
        let [qdd] = self.run(
            py,
            [("q", q, nq), ("v", v, nv), ("tau", tau, nv)],
            [&[nv]],
            |ws, [q, v, tau], [qdd]| {
                qdd.copy_from_slice(forward_dynamics(
                    m,
                    ws,
                    q,
                    v,
                    tau,
                    method,
                    &Externals::none(),
                )?);
                Ok(())
            },
        )?;
        Ok(qdd)
    }

    /// The joint-space mass matrix `M(q)` (symmetric): `(nv, nv)`, or `(N, nv, nv)`.
    fn mass_matrix<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Array<'py>> {
        let (m, nq, nv) = (&self.model, self.model.nq(), self.model.nv());
        let [mass] = self.run(py, [("q", q, nq)], [&[nv, nv]], |ws, [q], [out]| {
            row_major(out, crba(m, ws, q)?);
            Ok(())
        })?;
        Ok(mass)
    }

    /// The placement of URDF link `frame` in the world: `(translation, rotation)`, the link
    /// origin in world coordinates `(3,)` and the rotation from link to world coordinates
    /// `(3, 3)` (its columns the link axes; Pinocchio's `oMf`); `(N, 3)` and `(N, 3, 3)` for N
    /// states.
    fn frame_placement<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        frame: &str,
    ) -> PyResult<(Array<'py>, Array<'py>)> {
        let (m, nq) = (&self.model, self.model.nq());
        let frame = find_frame(m, frame).map_err(from_library)?;
        let [translation, rotation] = self.run(
            py,
            [("q", q, nq)],
            [&[3], &[3, 3]],
            |ws, [q], [translation, rotation]| {
                let x = frame_placement(m, ws, q, &frame)?;
                translation.copy_from_slice(x.trans.as_slice());
                // `x.rot` turns world into link coordinates: its transpose, row-major, is its
                // column-major storage.
                rotation.copy_from_slice(x.rot.as_slice());
                Ok(())
            },
        )?;
        Ok((translation, rotation))
    }

    /// The Jacobian of URDF link `frame`, `(6, nv)`, rows `[linear; angular]`, in `reference`
    /// "world" (world axes about the world origin), "local" (link axes at the link origin) or
    /// "local_world_aligned" (world axes at the link origin), Pinocchio's WORLD, LOCAL and
    /// LOCAL_WORLD_ALIGNED; `(N, 6, nv)` for N states.
    #[pyo3(signature = (q, frame, reference="world"))]
    fn frame_jacobian<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        frame: &str,
        reference: &str,
    ) -> PyResult<Array<'py>> {
        let (m, nq, nv) = (&self.model, self.model.nq(), self.model.nv());
        let frame = find_frame(m, frame).map_err(from_library)?;
        let reference = reference_frame(reference)?;
        let [j] = self.run(py, [("q", q, nq)], [&[6, nv]], |ws, [q], [j]| {
            row_major(j, frame_jacobian(m, ws, q, &frame, reference)?);
            Ok(())
        })?;
        Ok(j)
    }

    /// The centre of mass of the moving bodies: `(mass, com, J)`, their mass (kg, a float; links
    /// welded to the world are left out, as in Pinocchio's computeTotalMass, so a floating base
    /// counts every link), the position of their centre of mass in the world `(3,)` and its
    /// Jacobian `(3, nv)` (world axes); `(N,)`, `(N, 3)`, `(N, 3, nv)` for N states.
    fn center_of_mass<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
    ) -> PyResult<(Py<PyAny>, Array<'py>, Array<'py>)> {
        let (m, nq, nv) = (&self.model, self.model.nq(), self.model.nv());
        let [mass, com, j] = self.run(
            py,
            [("q", q, nq)],
            [&[], &[3], &[3, nv]],
            |ws, [q], [mass, com, j]| {
                let (c, jacobian) = center_of_mass_jacobian(m, ws, q)?;
                mass[0] = c.mass;
                com.copy_from_slice(c.position.as_slice());
                row_major(j, jacobian);
                Ok(())
            },
        )?;
        // One state's mass is a float (a 0-d array's item).
        let mass = match mass.ndim() {
            0 => mass.call_method0("item")?.unbind(),
            _ => mass.into_any().unbind(),
        };
        Ok((mass, com, j))
    }

    /// The derivatives of inverse dynamics at `(q, v, a)`: `(dtau_dq, dtau_dv, M)`, each
    /// `(nv, nv)` (`(N, nv, nv)` for N states), row `i` the derivative of `tau_i`, column `k`
    /// along velocity coordinate `k` (on the tangent of the configuration, as Pinocchio's
    /// computeRNEADerivatives); `M` the mass matrix, full.
    fn rnea_derivatives<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        v: &Bound<'py, PyAny>,
        a: &Bound<'py, PyAny>,
    ) -> PyResult<(Array<'py>, Array<'py>, Array<'py>)> {
        let m = &self.model;
        self.derivatives(py, q, v, ("a", a), |ws, q, v, a| {
            let d = rnea_derivatives(m, ws, q, v, a)?;
            Ok([d.dtau_dq, d.dtau_dv, d.mass_matrix])
        })
    }

    /// The derivatives of forward dynamics at `(q, v, tau)`: `(ddq_dq, ddq_dv, Minv)`, each
    /// `(nv, nv)` (`(N, nv, nv)` for N states), as Pinocchio's computeABADerivatives; `Minv`
    /// the inverse mass matrix, full.
    fn aba_derivatives<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        v: &Bound<'py, PyAny>,
        tau: &Bound<'py, PyAny>,
    ) -> PyResult<(Array<'py>, Array<'py>, Array<'py>)> {
        let m = &self.model;
        self.derivatives(py, q, v, ("tau", tau), |ws, q, v, tau| {
            let d = aba_derivatives(m, ws, q, v, tau, &Externals::none())?;
            Ok([d.ddq_dq, d.ddq_dv, d.minv])
        })
    }
}
