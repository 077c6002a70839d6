//! Links the embedded interpreter: the libpython of the build interpreter (`PYO3_PYTHON`, else
//! `python3` on PATH) into every binary, test and benchmark of this crate, with its libdir as
//! an rpath (without one the binary would load whatever libpython3.11.so the dynamic loader
//! finds first at run time).
//!
//! pyo3 does not link libpython itself: the workspace builds as maturin builds the wheel
//! (`PYO3_BUILD_EXTENSION_MODULE`, `.cargo/config.toml`), so the wheel's build reuses the
//! CLI's. An extension module must not name a libpython; the programs that embed one say so
//! here, for their own targets only (`rustc-link-arg` does not reach dependents, so the
//! wheel's library stays free of it).

use std::process::Command;

fn main() {
    // The shim for direct batch calls into the loaded libsumo (src/direct.rs).
    println!("cargo:rerun-if-changed=cpp/direct.cpp");
    cc::Build::new()
        .cpp(true)
        .file("cpp/direct.cpp")
        .flag_if_supported("-std=c++17")
        .compile("syncroad_direct");
    println!("cargo:rerun-if-env-changed=PYO3_PYTHON");
    let python = std::env::var("PYO3_PYTHON").unwrap_or_else(|_| "python3".to_string());
    let out = Command::new(&python)
        .args([
            "-c",
            "import sys, sysconfig; print(sysconfig.get_config_var('LIBDIR') or ''); print(sys.base_prefix); print(sysconfig.get_config_var('LDVERSION') or '')",
        ])
        .output();
    match out {
        Ok(o) if o.status.success() => {
            let text = String::from_utf8_lossy(&o.stdout).into_owned();
            let mut lines = text.lines().map(str::trim);
            let libdir = lines.next().unwrap_or_default().to_string();
            let home = lines.next().unwrap_or_default().to_string();
            let version = lines.next().unwrap_or_default().to_string();
            if !home.is_empty() {
                // The build interpreter's installation: the supervisor gives it to the worker
                // as PYTHONHOME, so the embedded interpreter finds its own standard library
                // whatever `python3` comes first on PATH (a system Python 3.11 has another
                // layout: `_posixsubprocess` went missing).
                println!("cargo:rustc-env=SYNCROAD_PYTHON_HOME={home}");
            }
            if !libdir.is_empty() {
                // Binaries of this crate (worker, tests) and, through the `rustc-link-arg`
                // of dependents' own build scripts, anything that opts in.
                println!("cargo:rustc-link-arg=-Wl,-rpath,{libdir}");
                println!("cargo:rustc-link-arg=-L{libdir}");
                // Also known to the crate: the supervisor puts it first in the worker's
                // LD_LIBRARY_PATH, so a worker re-executed from a binary without the rpath
                // (the `syncroad` CLI) still loads the build interpreter's libpython.
                println!("cargo:rustc-env=SYNCROAD_PYTHON_LIBDIR={libdir}");
                // For dependents' build scripts (`links = "syncroad-python"`): the CLI can set
                // the same rpath with `cargo:rustc-link-arg-bins=-Wl,-rpath,$DEP_SYNCROAD_PYTHON_LIBDIR`.
                println!("cargo::metadata=libdir={libdir}");
            }
            if version.is_empty() {
                println!("cargo:warning={python} names no LDVERSION; libpython is not linked");
            } else {
                println!("cargo:rustc-link-arg=-lpython{version}");
                println!("cargo::metadata=lib=python{version}");
            }
        }
        _ => println!(
            "cargo:warning=could not ask {python} for its libdir; no rpath set (set PYO3_PYTHON)"
        ),
    }
}
