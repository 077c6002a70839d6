//! The embedded CPython interpreter: loading libsumo from the project's virtualenv, and the one
//! place where Python exceptions become Rust errors.
//!
//! Every `PyErr` goes through [`py_error`], which keeps the Python traceback. No Python call is
//! ever unwrapped.

use pyo3::prelude::*;
use serde::{Deserialize, Serialize};

use crate::venv::{self, VenvError, BOOTSTRAP_COMMAND};

/// Errors of the embedded interpreter.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PythonError {
    /// The virtualenv could not be located.
    #[error(transparent)]
    Venv(#[from] VenvError),
    /// A package is missing from the virtualenv.
    #[error("Python module `{module}` is not installed in {site_packages} ({detail}); install the pinned SUMO packages with `{install}`")]
    MissingPackage {
        /// Module name.
        module: String,
        /// The site-packages folder that was searched.
        site_packages: String,
        /// The ImportError message.
        detail: String,
        /// The command that installs it.
        install: String,
    },
    /// A Python call raised.
    #[error("Python call `{call}` failed:\n{traceback}")]
    Call {
        /// What was called (with its arguments where they help).
        call: String,
        /// The formatted Python traceback and exception.
        traceback: String,
    },
}

/// Converts a Python exception into [`PythonError::Call`], keeping the traceback.
pub fn py_error(py: Python<'_>, call: impl Into<String>, err: PyErr) -> PythonError {
    PythonError::Call {
        call: call.into(),
        traceback: format_exception(py, &err),
    }
}

/// Formats an exception as `traceback.format_exception` does, without syncroad's own frames
/// (its adapter and loader, compiled from `syncroad_*.py`) and importlib's (`<frozen
/// importlib._bootstrap>`), in the exception and in those it was raised from: what is left is
/// the user's code. The chained exceptions are cleaned alike.
const FORMAT: &std::ffi::CStr = pyo3::ffi::c_str!(
    r#"
import traceback

HIDDEN = ("syncroad_user_law.py", "syncroad_libsumo_loader.py")


def _hidden(filename):
    return filename in HIDDEN or filename.startswith("<frozen importlib")


def format_exception(kind, value, tb):
    te = traceback.TracebackException(kind, value, tb)
    seen = set()
    todo = [te]
    while todo:
        e = todo.pop()
        if e is None or id(e) in seen:
            continue
        seen.add(id(e))
        e.stack = traceback.StackSummary.from_list([f for f in e.stack if not _hidden(f.filename)])
        todo += [e.__cause__, e.__context__]
    return "".join(te.format())
"#
);

/// The exception formatted without syncroad's frames ([`FORMAT`]) and cut to
/// [`syncroad_control::user_text::KEPT_BYTES`], falling back to the exception's `str`.
fn format_exception(py: Python<'_>, err: &PyErr) -> String {
    let formatted = (|| -> PyResult<String> {
        let module = PyModule::from_code(py, FORMAT, c"syncroad_format.py", c"syncroad_format")?;
        module
            .call_method1(
                "format_exception",
                (err.get_type(py), err.value(py), err.traceback(py)),
            )?
            .extract()
    })();
    let text = match formatted {
        Ok(s) => s.trim_end().to_string(),
        Err(_) => err.to_string(),
    };
    syncroad_control::user_text::kept(text)
}

/// Where a worker imports the SUMO packages (eclipse-sumo, libsumo) from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SumoPackages {
    /// The project's virtualenv, added to the embedded interpreter's path (see `venv`): the
    /// worker is a Rust binary of a checkout.
    ProjectVenv,
    /// The running interpreter's own `sys.path`: the worker is a Python process of an
    /// environment where the syncroad package and its pinned SUMO dependencies are installed.
    Interpreter,
}

/// How the pinned SUMO packages get into an interpreter's environment: they are dependencies
/// of the syncroad package.
const INTERPRETER_INSTALL: &str = "pip install syncroad (or pip install . in the repository)";

static PACKAGES: std::sync::OnceLock<SumoPackages> = std::sync::OnceLock::new();

/// Sets where this process imports libsumo from (first call wins; default the project venv).
pub fn use_packages(p: SumoPackages) {
    let _ = PACKAGES.set(p);
}

/// Where the embedded interpreter found its packages (logged at start, sent to the parent).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PythonInfo {
    /// `sys.version` of the embedded interpreter.
    pub python_version: String,
    /// `sys.prefix` (the base installation: a venv is added with `site.addsitedir`).
    pub sys_prefix: String,
    /// The virtualenv's site-packages that was added.
    pub site_packages: String,
    /// `libsumo.__file__`.
    pub libsumo_file: String,
    /// `libsumo.getVersion()`, e.g. `SUMO 1.28.0`.
    pub sumo_version: String,
    /// `sumo.SUMO_HOME` of the eclipse-sumo wheel (holds `bin/sumo`, `bin/netconvert`).
    pub sumo_home: String,
}

/// Puts the SUMO environment's packages on the interpreter's path (the project virtualenv's
/// site-packages for a Rust binary; nothing to add inside a Python process) and returns that
/// folder. Adding it twice is harmless.
pub fn add_packages(py: Python<'_>) -> Result<std::path::PathBuf, PythonError> {
    let sys = py
        .import("sys")
        .map_err(|e| py_error(py, "import sys", e))?;
    let vi = sys
        .getattr("version_info")
        .map_err(|e| py_error(py, "sys.version_info", e))?;
    let (major, minor): (u32, u32) = (
        vi.getattr("major")
            .and_then(|x| x.extract())
            .map_err(|e| py_error(py, "sys.version_info.major", e))?,
        vi.getattr("minor")
            .and_then(|x| x.extract())
            .map_err(|e| py_error(py, "sys.version_info.minor", e))?,
    );
    match PACKAGES.get().copied().unwrap_or(SumoPackages::ProjectVenv) {
        SumoPackages::ProjectVenv => add_project_venv(py, &format!("{major}.{minor}")),
        SumoPackages::Interpreter => py
            .import("sysconfig")
            .and_then(|m| m.call_method1("get_path", ("purelib",)))
            .and_then(|p| p.extract::<String>())
            .map(std::path::PathBuf::from)
            .map_err(|e| py_error(py, "sysconfig.get_path('purelib')", e)),
    }
}

/// How the worker loads SUMO (`libsumo_loader.py`: libsumo's compiled module without the
/// package's TraCI wrappers).
const LOADER: &std::ffi::CStr = pyo3::ffi::c_str!(include_str!("libsumo_loader.py"));

/// Adds the virtualenv's site-packages to the embedded interpreter and loads libsumo's compiled
/// module (`libsumo._libsumo`, whose functions the loop calls), returned with where it came
/// from.
pub fn load_libsumo(py: Python<'_>) -> Result<(Bound<'_, PyModule>, PythonInfo), PythonError> {
    let sys = py
        .import("sys")
        .map_err(|e| py_error(py, "import sys", e))?;
    let sp = add_packages(py)?;
    // Compiled once per process (executing it registers it in `sys.modules`); every later
    // job finds it there.
    let registered = sys
        .getattr("modules")
        .and_then(|m| m.get_item("syncroad_libsumo_loader"))
        .and_then(|m| m.cast_into::<PyModule>().map_err(PyErr::from));
    let loader = match registered {
        Ok(m) => m,
        Err(_) => PyModule::from_code(
            py,
            LOADER,
            c"syncroad_libsumo_loader.py",
            c"syncroad_libsumo_loader",
        )
        .map_err(|e| py_error(py, "syncroad's libsumo loader", e))?,
    };
    // A package that is not installed is named with what installs it.
    let load = |module: &str, function: &str| -> Result<Bound<'_, PyAny>, PythonError> {
        loader.call_method0(function).map_err(|e| {
            if e.is_instance_of::<pyo3::exceptions::PyImportError>(py) {
                PythonError::MissingPackage {
                    module: module.to_string(),
                    site_packages: sp.display().to_string(),
                    detail: e.value(py).to_string(),
                    install: match PACKAGES.get() {
                        Some(SumoPackages::Interpreter) => INTERPRETER_INSTALL.to_string(),
                        _ => BOOTSTRAP_COMMAND.to_string(),
                    },
                }
            } else {
                py_error(py, format!("loading {module}"), e)
            }
        })
    };
    let sumo_home: String = load("sumo", "sumo_home")?
        .extract()
        .map_err(|e| py_error(py, "SUMO_HOME", e))?;
    let (native, libsumo_file): (Bound<'_, PyModule>, String) = load("libsumo", "libsumo")?
        .extract()
        .map_err(|e| py_error(py, "libsumo._libsumo", e))?;
    let get_str = |obj: &Bound<'_, PyAny>, attr: &str| -> Result<String, PythonError> {
        obj.getattr(attr)
            .and_then(|x| x.str())
            .map(|s| s.to_string())
            .map_err(|e| py_error(py, attr.to_string(), e))
    };
    let version = native
        .call_method0("simulation_getVersion")
        .and_then(|v| v.get_item(1))
        .and_then(|v| v.extract::<String>())
        .map_err(|e| py_error(py, "libsumo.simulation.getVersion()", e))?;
    let info = PythonInfo {
        python_version: get_str(sys.as_any(), "version")?,
        sys_prefix: get_str(sys.as_any(), "prefix")?,
        site_packages: sp.display().to_string(),
        libsumo_file,
        sumo_version: version,
        sumo_home,
    };
    Ok((native, info))
}

/// Whether this process's libsumo already runs a simulation (the caller's own, in a Python
/// process), loaded as the worker loads it ([`load_libsumo`]).
pub fn libsumo_is_loaded(py: Python<'_>) -> Result<bool, PythonError> {
    let (native, _) = load_libsumo(py)?;
    native
        .call_method0("simulation_isLoaded")
        .and_then(|l| l.is_truthy())
        .map_err(|e| py_error(py, "libsumo.simulation.isLoaded()", e))
}

/// Adds the project virtualenv's site-packages to the interpreter's path and returns it.
fn add_project_venv(py: Python<'_>, version: &str) -> Result<std::path::PathBuf, PythonError> {
    let venv_dir = venv::find_venv()?;
    let sp = venv::site_packages(&venv_dir, version)?;
    let site = py
        .import("site")
        .map_err(|e| py_error(py, "import site", e))?;
    site.call_method1("addsitedir", (sp.to_string_lossy().as_ref(),))
        .map_err(|e| py_error(py, format!("site.addsitedir({})", sp.display()), e))?;
    Ok(sp)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn python_errors_keep_the_traceback() {
        Python::initialize();
        Python::attach(|py| {
            let code =
                c"def inner():\n    raise ValueError('bad speed 7')\n\ndef outer():\n    inner()\n";
            let m = PyModule::from_code(py, code, c"probe.py", c"probe").expect("valid code");
            let err = m.call_method0("outer").expect_err("raises");
            let e = py_error(py, "probe.outer()", err);
            let msg = e.to_string();
            assert!(
                msg.starts_with("Python call `probe.outer()` failed:\nTraceback"),
                "{msg}"
            );
            assert!(msg.contains("in inner"), "{msg}");
            assert!(msg.ends_with("ValueError: bad speed 7"), "{msg}");
        });
    }

    #[test]
    fn missing_package_says_what_to_run() {
        let e = PythonError::MissingPackage {
            module: "libsumo".into(),
            site_packages: "/r/.venv/lib/python3.11/site-packages".into(),
            detail: "No module named 'libsumo'".into(),
            install: BOOTSTRAP_COMMAND.into(),
        };
        assert_eq!(
            e.to_string(),
            "Python module `libsumo` is not installed in /r/.venv/lib/python3.11/site-packages (No module named 'libsumo'); install the pinned SUMO packages with `bash python-host/bootstrap.sh`"
        );
    }
}
