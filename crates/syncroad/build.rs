//! Links the `syncroad` binary, its tests and its example with the libpython that
//! syncroad-sumo was built against (pyo3 leaves the linking to the programs that embed the
//! interpreter, see syncroad-sumo's build script), with its libdir as an rpath, so the binary
//! never loads another libpython3.11.so found first by the dynamic loader.
fn main() {
    println!("cargo:rerun-if-env-changed=DEP_SYNCROAD_PYTHON_LIBDIR");
    println!("cargo:rerun-if-env-changed=DEP_SYNCROAD_PYTHON_LIB");
    if let Ok(dir) = std::env::var("DEP_SYNCROAD_PYTHON_LIBDIR") {
        println!("cargo:rustc-link-arg=-Wl,-rpath,{dir}");
        println!("cargo:rustc-link-arg=-L{dir}");
    }
    if let Ok(lib) = std::env::var("DEP_SYNCROAD_PYTHON_LIB") {
        println!("cargo:rustc-link-arg=-l{lib}");
    }
}
