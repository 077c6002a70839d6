//! Gives the `syncroad` binary the rpath of the libpython that syncroad-sumo was built
//! against, so it never loads another libpython3.11.so found first by the dynamic loader.
fn main() {
    println!("cargo:rerun-if-env-changed=DEP_SYNCROAD_PYTHON_LIBDIR");
    if let Ok(dir) = std::env::var("DEP_SYNCROAD_PYTHON_LIBDIR") {
        println!("cargo:rustc-link-arg-bins=-Wl,-rpath,{dir}");
    }
}
