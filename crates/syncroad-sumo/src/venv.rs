//! Finding the Python virtualenv that holds the pinned SUMO packages.
//!
//! The embedded interpreter ignores `VIRTUAL_ENV` and would search `PATH` for `python3`, so the
//! venv is located explicitly, in this order:
//! 1. the `SYNCROAD_VENV` environment variable (must exist when set);
//! 2. `.venv` in the nearest ancestor of the running executable that holds
//!    `python-host/requirements.txt` (a checkout with `target/` inside it);
//! 3. `.venv` of the checkout this crate was compiled from (`CARGO_MANIFEST_DIR/../..`).

use std::path::{Path, PathBuf};

/// The command that creates the virtualenv.
pub const BOOTSTRAP_COMMAND: &str = "bash python-host/bootstrap.sh";

/// Errors locating the virtualenv.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum VenvError {
    /// `SYNCROAD_VENV` names a folder that is not a virtualenv.
    #[error("SYNCROAD_VENV={path} is not a virtualenv (no bin/python in it); create it with `SYNCROAD_VENV={path} {BOOTSTRAP_COMMAND}` or unset SYNCROAD_VENV")]
    EnvVarNotAVenv {
        /// The value of the variable.
        path: String,
    },
    /// No candidate folder exists.
    #[error("no SUMO virtualenv found (looked for {tried}); create it with `{BOOTSTRAP_COMMAND}` in the repository, or set SYNCROAD_VENV")]
    NotFound {
        /// The candidates, comma separated.
        tried: String,
    },
    /// The venv holds no SUMO package with this program.
    #[error("the virtualenv {venv} has no SUMO program `{name}` (lib/python3.*/site-packages/sumo/bin/{name}); install the pinned SUMO packages: `{BOOTSTRAP_COMMAND}`")]
    NoProgram {
        /// The program.
        name: String,
        /// The venv folder.
        venv: String,
    },
    /// The venv exists but not for the embedded interpreter's version.
    #[error("the virtualenv {venv} has no lib/python{version}/site-packages, so it was not built for the embedded Python {version}; rebuild it: `rm -rf {venv} && {BOOTSTRAP_COMMAND}`")]
    NoSitePackages {
        /// The venv folder.
        venv: String,
        /// `major.minor` of the embedded interpreter.
        version: String,
    },
}

/// A program of the SUMO package in the virtualenv (`sumo`, `sumo-gui`, `netconvert`):
/// `<venv>/lib/python3.*/site-packages/sumo/bin/<name>`, and the package's folder (SUMO_HOME).
pub fn sumo_program(name: &str) -> Result<(PathBuf, PathBuf), VenvError> {
    let venv = find_venv()?;
    let lib = venv.join("lib");
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(&lib)
        .map(|d| d.flatten().map(|e| e.path()).collect())
        .unwrap_or_default();
    dirs.sort();
    for d in dirs {
        let home = d.join("site-packages").join("sumo");
        let bin = home.join("bin").join(name);
        if bin.is_file() {
            return Ok((bin, home));
        }
    }
    Err(VenvError::NoProgram {
        name: name.to_string(),
        venv: venv.display().to_string(),
    })
}

/// Locates the virtualenv (see the module documentation for the search order).
pub fn find_venv() -> Result<PathBuf, VenvError> {
    let exe = std::env::current_exe().ok();
    find_venv_from(
        std::env::var_os("SYNCROAD_VENV").map(PathBuf::from),
        exe.as_deref(),
        Path::new(env!("CARGO_MANIFEST_DIR")),
    )
}

fn is_venv(p: &Path) -> bool {
    p.join("bin").join("python").exists() || p.join("pyvenv.cfg").is_file()
}

/// The search of [`find_venv`] with its inputs made explicit (for tests).
pub fn find_venv_from(
    env_var: Option<PathBuf>,
    exe: Option<&Path>,
    manifest_dir: &Path,
) -> Result<PathBuf, VenvError> {
    if let Some(p) = env_var {
        return if is_venv(&p) {
            Ok(p)
        } else {
            Err(VenvError::EnvVarNotAVenv {
                path: p.display().to_string(),
            })
        };
    }
    let mut tried = Vec::new();
    if let Some(exe) = exe {
        for dir in exe.ancestors().skip(1) {
            if dir.join("python-host").join("requirements.txt").is_file() {
                let v = dir.join(".venv");
                if is_venv(&v) {
                    return Ok(v);
                }
                tried.push(v.display().to_string());
                break;
            }
        }
    }
    if let Some(repo) = manifest_dir.parent().and_then(Path::parent) {
        let v = repo.join(".venv");
        if is_venv(&v) {
            return Ok(v);
        }
        let s = v.display().to_string();
        if !tried.contains(&s) {
            tried.push(s);
        }
    }
    Err(VenvError::NotFound {
        tried: tried.join(", "),
    })
}

/// The syncroad checkout (holding `sumo-nets/` and `python-host/`): `SYNCROAD_REPO` if set,
/// else the nearest ancestor of the running executable holding `python-host/requirements.txt`,
/// else the checkout this crate was compiled from.
pub fn repo_dir() -> PathBuf {
    if let Some(p) = std::env::var_os("SYNCROAD_REPO") {
        return PathBuf::from(p);
    }
    if let Ok(exe) = std::env::current_exe() {
        if let Some(dir) = exe
            .ancestors()
            .skip(1)
            .find(|d| d.join("python-host").join("requirements.txt").is_file())
        {
            return dir.to_path_buf();
        }
    }
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// `<venv>/lib/python<version>/site-packages`, checked to exist.
pub fn site_packages(venv: &Path, version: &str) -> Result<PathBuf, VenvError> {
    let sp = venv
        .join("lib")
        .join(format!("python{version}"))
        .join("site-packages");
    if sp.is_dir() {
        Ok(sp)
    } else {
        Err(VenvError::NoSitePackages {
            venv: venv.display().to_string(),
            version: version.to_string(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn env_var_must_point_at_a_venv() {
        let err = find_venv_from(
            Some(PathBuf::from("/nonexistent/venv")),
            None,
            Path::new("/nonexistent/a/b"),
        )
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "SYNCROAD_VENV=/nonexistent/venv is not a virtualenv (no bin/python in it); create it with `SYNCROAD_VENV=/nonexistent/venv bash python-host/bootstrap.sh` or unset SYNCROAD_VENV"
        );
    }

    #[test]
    fn missing_venv_names_the_bootstrap_command() {
        let err = find_venv_from(None, None, Path::new("/nonexistent/crates/x")).unwrap_err();
        assert_eq!(
            err.to_string(),
            "no SUMO virtualenv found (looked for /nonexistent/.venv); create it with `bash python-host/bootstrap.sh` in the repository, or set SYNCROAD_VENV"
        );
    }

    #[test]
    fn wrong_python_version_is_named() {
        let err = site_packages(Path::new("/nonexistent/.venv"), "3.11").unwrap_err();
        assert!(err.to_string().contains("lib/python3.11/site-packages"));
        assert!(err.to_string().contains("rm -rf /nonexistent/.venv"));
    }
}
