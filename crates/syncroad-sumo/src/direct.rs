//! Direct batch calls into the libsumo that CPython has loaded.
//!
//! The Python module `libsumo` is a SWIG wrapper around the static functions of
//! `libsumo::Vehicle`, and its shared object (`libsumo/_libsumo.so`) exports them. Once Python
//! has imported it and started the simulation, the worker looks the functions up in that very
//! library (`dlopen` with `RTLD_NOLOAD` returns the loaded copy, so the simulation state is the
//! one Python started) and calls them through a small C++ shim (`cpp/direct.cpp`) once per
//! step for all vehicles: one `getSpeed` and one `setSpeed` per vehicle without an interpreter
//! round trip each. The inflows' controlled vehicles, which come and go, are read and
//! commanded the same way through ids of their own ([`CppIds`]): their speeds,
//! `getLeader` with the leader's speed, `getAllowedSpeed`, `setSpeed`. Python still starts,
//! steps and closes SUMO.
//!
//! If the library or a symbol is missing (another libsumo build), [`Direct::load`] returns
//! `None` and the loop keeps the Python getters.

use std::ffi::{c_char, c_void, CStr, CString};
use std::mem::MaybeUninit;

/// Mangled names of the functions used (GCC's C++11 ABI, as in the pinned wheels).
const GET_SPEED: &str =
    "_ZN7libsumo7Vehicle8getSpeedERKNSt7__cxx1112basic_stringIcSt11char_traitsIcESaIcEEE";
const GET_DISTANCE: &str =
    "_ZN7libsumo7Vehicle11getDistanceERKNSt7__cxx1112basic_stringIcSt11char_traitsIcESaIcEEE";
const SET_SPEED: &str =
    "_ZN7libsumo7Vehicle8setSpeedERKNSt7__cxx1112basic_stringIcSt11char_traitsIcESaIcEEEd";
const GET_FUEL: &str =
    "_ZN7libsumo7Vehicle18getFuelConsumptionERKNSt7__cxx1112basic_stringIcSt11char_traitsIcESaIcEEE";
const GET_CO2: &str =
    "_ZN7libsumo7Vehicle14getCO2EmissionERKNSt7__cxx1112basic_stringIcSt11char_traitsIcESaIcEEE";
const GET_LEADER: &str =
    "_ZN7libsumo7Vehicle9getLeaderERKNSt7__cxx1112basic_stringIcSt11char_traitsIcESaIcEEEd";
const GET_ALLOWED_SPEED: &str =
    "_ZN7libsumo7Vehicle15getAllowedSpeedERKNSt7__cxx1112basic_stringIcSt11char_traitsIcESaIcEEE";
const COLLIDING: &str = "_ZN7libsumo10Simulation26getCollidingVehiclesNumberEv";
const TELEPORTS: &str = "_ZN7libsumo10Simulation25getStartingTeleportNumberEv";

#[repr(C)]
struct SrIds {
    _private: [u8; 0],
}

extern "C" {
    fn sr_ids_new(ids: *const *const c_char, lens: *const usize, n: usize) -> *mut SrIds;
    fn sr_ids_free(ids: *mut SrIds);
    fn sr_get_f64(
        f: *mut c_void,
        ids: *const SrIds,
        out: *mut f64,
        err: *mut c_char,
        errlen: usize,
    ) -> usize;
    fn sr_get_ints(
        fns: *const *mut c_void,
        out: *mut i32,
        n: usize,
        err: *mut c_char,
        errlen: usize,
    ) -> usize;
    fn sr_set_f64(
        f: *mut c_void,
        ids: *const SrIds,
        input: *const f64,
        err: *mut c_char,
        errlen: usize,
    ) -> usize;
    #[allow(clippy::too_many_arguments)]
    fn sr_leaders(
        leader: *mut c_void,
        speed: *mut c_void,
        ids: *const SrIds,
        dist: f64,
        speed_out: *mut f64,
        gap_out: *mut f64,
        err: *mut c_char,
        errlen: usize,
    ) -> usize;
}

/// Vehicle ids as C++ strings, made once for as long as the set of vehicles stays the same.
pub struct CppIds {
    ptr: *mut SrIds,
    n: usize,
}

impl CppIds {
    /// The ids `ids`; `None` if the shim could not allocate them.
    pub fn new<S: AsRef<str>>(ids: &[S]) -> Option<Self> {
        let ptrs: Vec<*const c_char> = ids.iter().map(|s| s.as_ref().as_ptr().cast()).collect();
        let lens: Vec<usize> = ids.iter().map(|s| s.as_ref().len()).collect();
        // SAFETY: `ptrs[i]` points at `lens[i]` bytes of `ids[i]`, alive during the call; the
        // shim copies them into std::strings.
        let ptr = unsafe { sr_ids_new(ptrs.as_ptr(), lens.as_ptr(), ids.len()) };
        (!ptr.is_null()).then_some(Self { ptr, n: ids.len() })
    }

    /// `out[i] = f(ids[i])`.
    fn get(&self, f: *mut c_void, out: &mut [f64]) -> Result<(), DirectError> {
        assert_eq!(out.len(), self.n, "one value per vehicle");
        let mut err = ErrBuf::new();
        // SAFETY: `f` is `double(const std::string&)` from the loaded libsumo, `self.ptr` holds
        // `n` strings and `out` has room for `n` values; the shim catches every exception.
        let r = unsafe { sr_get_f64(f, self.ptr, out.as_mut_ptr(), err.ptr(), err.len()) };
        check(r, &err)
    }

    /// `f(ids[i], input[i])`.
    fn set(&self, f: *mut c_void, input: &[f64]) -> Result<(), DirectError> {
        assert_eq!(input.len(), self.n, "one value per vehicle");
        let mut err = ErrBuf::new();
        // SAFETY: as in `get`, with `void(const std::string&, double)`.
        let r = unsafe { sr_set_f64(f, self.ptr, input.as_ptr(), err.ptr(), err.len()) };
        check(r, &err)
    }
}

impl Drop for CppIds {
    fn drop(&mut self) {
        // SAFETY: `ptr` came from sr_ids_new and is freed once.
        unsafe { sr_ids_free(self.ptr) }
    }
}

fn check(r: usize, err: &ErrBuf) -> Result<(), DirectError> {
    if r == 0 {
        return Ok(());
    }
    Err(DirectError {
        vehicle: r - 1,
        message: err.message(),
    })
}

/// A failed call: the vehicle index and the C++ exception's message.
#[derive(Debug, Clone, PartialEq)]
pub struct DirectError {
    /// Index of the vehicle whose call threw.
    pub vehicle: usize,
    /// `what()` of the exception.
    pub message: String,
}

/// Room for the message of a C++ exception. Left uninitialised: the shim writes it, NUL
/// terminated, only when a call throws, and it is read only then (the calls run every step;
/// zeroing 512 bytes each time showed in the loop's profile).
struct ErrBuf([MaybeUninit<c_char>; 512]);

impl ErrBuf {
    fn new() -> Self {
        Self([MaybeUninit::uninit(); 512])
    }

    fn ptr(&mut self) -> *mut c_char {
        self.0.as_mut_ptr().cast()
    }

    fn len(&self) -> usize {
        self.0.len()
    }

    /// The message, once a shim reported a failure (and so wrote it).
    fn message(&self) -> String {
        // SAFETY: the shim strncpy's the message (padding with NULs) and NUL-terminates the
        // buffer's last byte whenever it reports an error, the only time this is called.
        unsafe { CStr::from_ptr(self.0.as_ptr().cast()) }
            .to_string_lossy()
            .into_owned()
    }
}

/// Resolved functions and the vehicle ids as C++ strings.
pub struct Direct {
    get_speed: *mut c_void,
    get_distance: *mut c_void,
    set_speed: *mut c_void,
    /// `getCollidingVehiclesNumber`, `getStartingTeleportNumber`.
    counts: [*mut c_void; 2],
    /// `getFuelConsumption`, `getCO2Emission` (the measurements' every-step reads), where the
    /// library exports them.
    emissions: Option<[*mut c_void; 2]>,
    /// `getLeader` (the inflows' controlled vehicles).
    get_leader: *mut c_void,
    /// `getAllowedSpeed` (the inflows' controlled vehicles).
    get_allowed_speed: *mut c_void,
    ids: CppIds,
}

impl Direct {
    /// Looks the functions up in the already loaded library `so_path` (the `__file__` of
    /// `libsumo._libsumo`) for vehicles `ids`; `None` if anything is missing.
    pub fn load(so_path: &str, ids: &[String]) -> Option<Self> {
        let path = CString::new(so_path).ok()?;
        // SAFETY: dlopen with RTLD_NOLOAD only returns a handle to a library already loaded in
        // this process (or NULL); it never runs constructors of a new copy.
        let handle = unsafe { libc::dlopen(path.as_ptr(), libc::RTLD_NOW | libc::RTLD_NOLOAD) };
        if handle.is_null() {
            return None;
        }
        let sym = |name: &str| -> Option<*mut c_void> {
            let c = CString::new(name).ok()?;
            // SAFETY: `handle` is a live handle from dlopen; dlsym returns NULL if absent.
            let p = unsafe { libc::dlsym(handle, c.as_ptr()) };
            (!p.is_null()).then_some(p)
        };
        let (get_speed, get_distance, set_speed) =
            (sym(GET_SPEED)?, sym(GET_DISTANCE)?, sym(SET_SPEED)?);
        let (colliding, teleports) = (sym(COLLIDING)?, sym(TELEPORTS)?);
        Some(Self {
            get_speed,
            get_distance,
            set_speed,
            counts: [colliding, teleports],
            emissions: sym(GET_FUEL).zip(sym(GET_CO2)).map(|(f, c)| [f, c]),
            get_leader: sym(GET_LEADER)?,
            get_allowed_speed: sym(GET_ALLOWED_SPEED)?,
            ids: CppIds::new(ids)?,
        })
    }

    fn get(&self, f: *mut c_void, out: &mut [f64]) -> Result<(), DirectError> {
        self.ids.get(f, out)
    }

    /// `vehicle.getSpeed` of every vehicle.
    pub fn speeds(&self, out: &mut [f64]) -> Result<(), DirectError> {
        self.get(self.get_speed, out)
    }

    /// `vehicle.getDistance` (odometer) of every vehicle.
    pub fn odometers(&self, out: &mut [f64]) -> Result<(), DirectError> {
        self.get(self.get_distance, out)
    }

    /// `vehicle.getFuelConsumption` \[mg/s\] of every vehicle; `None` where the library does
    /// not export it (the caller asks Python then).
    pub fn fuel(&self, out: &mut [f64]) -> Option<Result<(), DirectError>> {
        self.emissions.map(|[fuel, _]| self.get(fuel, out))
    }

    /// `vehicle.getCO2Emission` \[mg/s\] of every vehicle; `None` as for [`Direct::fuel`].
    pub fn co2(&self, out: &mut [f64]) -> Option<Result<(), DirectError>> {
        self.emissions.map(|[_, co2]| self.get(co2, out))
    }

    /// `simulation.getCollidingVehiclesNumber` (vehicles in a collision this step) and
    /// `simulation.getStartingTeleportNumber` (teleports that started this step), in one call.
    /// A failure names the call: `Err((k, message))`, k = 0 for the first, 1 for the second.
    pub fn safety_counts(&self) -> Result<(usize, usize), (usize, String)> {
        let mut n = [0i32; 2];
        get_ints(&self.counts, &mut n)?;
        let count = |k: usize| usize::try_from(n[k]).unwrap_or(0);
        Ok((count(0), count(1)))
    }

    /// `vehicle.setSpeed` of every vehicle.
    pub fn set_speeds(&self, speeds: &[f64]) -> Result<(), DirectError> {
        self.ids.set(self.set_speed, speeds)
    }

    // The calls for a set of vehicles of its own, `ids`: the inflows' controlled vehicles,
    // which come and go.

    /// `vehicle.getSpeed` of each of `ids`.
    pub fn speeds_of(&self, ids: &CppIds, out: &mut [f64]) -> Result<(), DirectError> {
        ids.get(self.get_speed, out)
    }

    /// `vehicle.getAllowedSpeed` (the lane's speed limit for the vehicle) of each of `ids`.
    pub fn allowed_speeds_of(&self, ids: &CppIds, out: &mut [f64]) -> Result<(), DirectError> {
        ids.get(self.get_allowed_speed, out)
    }

    /// `vehicle.getLeader(id, dist)` of each of `ids` and, where it names a vehicle at a gap
    /// ≥ 0, that vehicle's `getSpeed`: `speed[i]` and `gap[i]`, NaN for both where nobody is
    /// ahead within `dist`.
    pub fn leaders_of(
        &self,
        ids: &CppIds,
        dist: f64,
        speed: &mut [f64],
        gap: &mut [f64],
    ) -> Result<(), DirectError> {
        assert_eq!(speed.len(), ids.n, "one value per vehicle");
        assert_eq!(gap.len(), ids.n, "one value per vehicle");
        let mut err = ErrBuf::new();
        // SAFETY: `get_leader` is `std::pair<std::string, double>(const std::string&, double)` and
        // `get_speed` `double(const std::string&)` from the loaded libsumo; `ids` holds `n`
        // strings, `speed` and `gap` room for `n` values each; the shim catches every
        // exception.
        let r = unsafe {
            sr_leaders(
                self.get_leader,
                self.get_speed,
                ids.ptr,
                dist,
                speed.as_mut_ptr(),
                gap.as_mut_ptr(),
                err.ptr(),
                err.len(),
            )
        };
        check(r, &err)
    }

    /// `vehicle.setSpeed` of each of `ids`.
    pub fn set_speeds_of(&self, ids: &CppIds, speeds: &[f64]) -> Result<(), DirectError> {
        ids.set(self.set_speed, speeds)
    }
}

/// `out[k] = fns[k]()` for `int()` functions, in one call into the shim; a failure names the
/// call that threw: `Err((k, message))`.
fn get_ints(fns: &[*mut c_void], out: &mut [i32]) -> Result<(), (usize, String)> {
    assert_eq!(fns.len(), out.len(), "one value per function");
    let mut err = ErrBuf::new();
    // SAFETY: each of `fns` is an `int()` function (libsumo's counts), `out` has room for one
    // value each; the shim catches every exception.
    let r = unsafe {
        sr_get_ints(
            fns.as_ptr(),
            out.as_mut_ptr(),
            fns.len(),
            err.ptr(),
            err.len(),
        )
    };
    match r {
        0 => Ok(()),
        k => Err((k - 1, err.message())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    extern "C" fn seven() -> i32 {
        7
    }

    extern "C" {
        fn sr_test_throw() -> i32;
    }

    /// The counts come back through the shim, and a C++ exception's message arrives whole in
    /// the buffer that is left uninitialised until the shim writes it.
    #[test]
    fn counts_and_a_thrown_message_come_back_through_the_shim() {
        let ok = seven as extern "C" fn() -> i32 as *mut c_void;
        let throws = sr_test_throw as unsafe extern "C" fn() -> i32 as *mut c_void;
        let mut out = [0i32; 2];
        assert_eq!(get_ints(&[ok, ok], &mut out), Ok(()));
        assert_eq!(out, [7, 7]);
        let mut out = [0i32; 3];
        let e = get_ints(&[ok, throws, ok], &mut out).unwrap_err();
        assert_eq!(e, (1, "Vehicle 'ghost' is not known".to_string()));
        assert_eq!(out[0], 7, "the calls before the failure are kept");
    }
}
