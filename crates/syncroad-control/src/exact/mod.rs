//! Exact stability of velocity synchronization (issue 5).
//!
//! Theorem `thm.1` / `thm.delay-agent` of the paper give a *sufficient* condition for the
//! delayed-driver network (eq. `chandler+`): a strongly connected graph and
//! `α_j d_j^+ < 1/2`. This module computes the *exact* answer, so that the conservatism of
//! the theorem can be measured:
//!
//! * [`lambert_w`](mod@lambert_w) — complex Lambert W on all branches (Halley iteration);
//! * [`ring_modes`] — uniform rings: Fourier modes and Lambert W roots, closed-form critical
//!   gains per mode (the fast path and the test oracle);
//! * [`collocation`] — any weighted graph with heterogeneous delays: spectral collocation of
//!   the infinitesimal generator, Newton refinement on the characteristic matrix;
//! * [`argument_principle`] — an independent count of the roots right of a line (certifies
//!   that the collocation missed nothing);
//! * [`critical`] — critical gain / delay scale and the conservatism ratio against Theorem 1;
//! * [`cacc_modes`](mod@cacc_modes) — CACC platoon (eqs. `veh1`, `veh-proto1`,
//!   `veh-proto2`): closed-loop eigenvalues next to Theorem `thm.cacc`;
//! * [`string_stability`](mod@string_stability) — gap-error transfer peaks and a
//!   braking-wave simulation;
//! * [`platoon_scaling`](mod@platoon_scaling) — least-stable eigenvalue of bidirectional
//!   platoons against their size, with the fitted exponent (Barooah, Mehta & Hespanha);
//! * [`leader_amplification`](mod@leader_amplification) — peak gain from a leader's speed to
//!   every follower's, on any graph (the worst amplification along a platoon);
//! * [`acyclic`] — exact roots of acyclic networks (predecessor following behind a leader),
//!   where identical drivers give roots of high multiplicity;
//! * [`gaps`] — the gap certificate: where the gaps settle, the worst-case shrinkage per m/s
//!   of speed perturbation, the scenario's own run (delayed drivers and CACC platoons);
//! * [`analysis`] — a whole scenario: the method chosen for its structure and one verdict;
//! * [`report`] — combined serializable reports with plain-text tables for a CLI.
//!
//! Inputs are plain data: an adjacency matrix `A = (a_ij)` with `a_ij ≥ 0` and zero diagonal
//! as `nalgebra::DMatrix<f64>`, delays as `&[f64]`.
#![warn(missing_docs)]

pub mod acyclic;
pub mod analysis;
pub mod argument_principle;
pub(crate) mod banded;
pub mod boundaries;
pub mod cacc_modes;
pub mod collocation;
mod count_reference;
pub mod critical;
pub(crate) mod dual;
pub mod gaps;
pub mod lambert_w;
pub mod leader_amplification;
pub mod linear;
pub mod platoon_scaling;
pub mod report;
pub mod ring_modes;
mod schur_eigenvalues;
pub(crate) mod sparse_lu;
pub mod string_stability;

pub use acyclic::{acyclic_roots, AcyclicError, AcyclicReport, DriverRoot};
pub use analysis::{analyse, AnalysisError, ExactVerdict, StabilityReport};
pub use argument_principle::{count_roots_right_of, ArgumentPrincipleError, RootCount};
pub use boundaries::{gain_delay_boundaries, Boundaries, Method};
pub use cacc_modes::{
    cacc_critical, cacc_modes, CaccCondition, CaccCritical, CaccError, CaccModes, CaccParams,
};
pub use collocation::{
    characteristic_matrix, rightmost_roots, rightmost_roots_shift_invert, CollocationError,
    CollocationOptions, RefinedRoot, RootsReport,
};
pub use critical::{critical_scale, CriticalError, CriticalReport, ReferenceTheorem};
pub use lambert_w::{lambert_w, LambertWError};
pub use leader_amplification::{leader_amplification, LeaderAmplification};
pub use platoon_scaling::{platoon_scaling, PlatoonLaw, PlatoonScaling, PlatoonScalingError};
pub use report::{
    analyse_cacc, analyse_network, analyse_network_reporting, certify_roots, CaccReport,
    NetworkStabilityReport, ReportError, RootsCertificate,
};
pub use ring_modes::{RingError, RingModes, UniformRing};
pub use string_stability::{
    chandler_string_peak, string_stability, LeaderDisturbance, StringStabilityError,
    StringStabilityOptions, StringStabilityReport,
};

use num_complex::Complex64;
use serde::Serialize;

/// A characteristic root `s = re + i·im` [1/s], as a serializable pair.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Root {
    /// Real part: decay (negative) or growth (positive) rate [1/s].
    pub re: f64,
    /// Imaginary part: angular frequency [rad/s].
    pub im: f64,
}

impl From<Complex64> for Root {
    fn from(s: Complex64) -> Self {
        Root { re: s.re, im: s.im }
    }
}

impl From<Root> for Complex64 {
    fn from(r: Root) -> Self {
        Complex64::new(r.re, r.im)
    }
}
