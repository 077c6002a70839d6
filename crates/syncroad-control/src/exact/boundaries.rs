//! The two stability boundaries of a delayed-driver scenario in the plane of a gain scale c
//! (A → cA) and a delay scale r (α → rα). Scaling changes `det(sI + diag(e^{−srα}) cL)` into
//! `det(zI + diag(e^{−zα}) crL)/r` with z = rs, so both boundaries are hyperbolas `c·r = const`:
//! Theorem 1 (1+) certifies below its constant, and the network is exactly stable below the
//! critical gain scale of the unscaled scenario.

use serde::Serialize;

use super::analysis::{below_resolution, network_matrices, uniform_ring};
use super::{acyclic_roots, critical_scale, rightmost_roots, CollocationOptions, UniformRing};
use crate::scenario::Scenario;
use crate::scenario::{DelayedDriverModel, Model};
use crate::theory;

/// How the exact roots of a delayed-driver network are computed, chosen once from its
/// structure: the one dispatch behind the boundaries and `map`'s grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Method {
    /// A uniform ring: Fourier modes and Lambert W (any size, closed form).
    UniformRing(UniformRing),
    /// An acyclic network (a chain behind a leader): roots per driver, closed form.
    Acyclic,
    /// Any other network: collocation, certified by root counts.
    Network,
}

impl Method {
    /// The method for the scenario's delayed-driver model `m`.
    pub fn of(sc: &Scenario, m: &DelayedDriverModel) -> Self {
        if let Some(r) = uniform_ring(sc, m) {
            return Self::UniformRing(r);
        }
        let (a, d) = network_matrices(m);
        if acyclic_roots(&a, &d).is_ok() {
            Self::Acyclic
        } else {
            Self::Network
        }
    }

    /// Spectral abscissa (the roots other than the consensus root) of `scaled`, the network
    /// with its gains scaled by `c` and its delays by `r` (a uniform ring scales its own
    /// parameters by `c` and `r`). None where it cannot be computed, including a network whose
    /// gain × delay is below the exact analysis' resolution.
    pub fn abscissa(&self, scaled: &DelayedDriverModel, c: f64, r: f64) -> Option<f64> {
        if below_resolution(scaled) {
            return None;
        }
        match self {
            Self::UniformRing(ring) => UniformRing::new(
                ring.vehicles,
                ring.gain_front * c,
                ring.gain_back * c,
                ring.delay_s * r,
            )
            .ok()?
            .modes()
            .ok()
            .map(|modes| modes.abscissa),
            Self::Acyclic => {
                let (a, d) = network_matrices(scaled);
                acyclic_roots(&a, &d).ok().map(|x| x.abscissa)
            }
            Self::Network => {
                let (a, d) = network_matrices(scaled);
                rightmost_roots(&a, &d, &CollocationOptions::default())
                    .ok()
                    .map(|x| x.abscissa)
            }
        }
    }

    /// The critical gain scale of `m` and whether it is certified (a closed form is).
    pub fn critical_gain_scale(&self, m: &DelayedDriverModel) -> (Option<f64>, bool) {
        if let Self::UniformRing(r) = self {
            return (r.modes().ok().map(|x| x.critical_gain_scale), true);
        }
        let (a, d) = network_matrices(m);
        if let Self::Acyclic = self {
            return match acyclic_roots(&a, &d) {
                Ok(x) => (Some(x.critical_gain_scale), true),
                Err(_) => (None, false),
            };
        }
        match critical_scale(&a, &d, &CollocationOptions::default()) {
            Ok(c) => (Some(c.critical_gain_scale), c.certified),
            Err(_) => (None, false),
        }
    }
}

/// The constants of the two hyperbolas `c·r = const`.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Boundaries {
    /// Theorem 1 (1+) holds for `c·r` below this.
    pub theorem1_product: f64,
    /// Exact stability for `c·r` below this (the critical gain scale), when computed.
    pub exact_product: Option<f64>,
    /// The exact constant is a closed form or certified by root counts at `c*`
    /// ([`super::CriticalReport::certified`]); false: UNCERTIFIED.
    pub exact_certified: bool,
}

/// The boundaries of a delayed-driver scenario (`None` for other models).
pub fn gain_delay_boundaries(sc: &Scenario) -> Option<Boundaries> {
    let Model::DelayedDriver(m) = sc.model() else {
        return None;
    };
    let theorem1_product = match &m.leader {
        None => theory::theorem1(&m.graph, &m.delay_s).max_gain_scale,
        Some((_, b)) => theory::theorem1_plus(&m.graph, &m.delay_s, b).max_gain_scale,
    };
    let (exact_product, exact_certified) = Method::of(sc, m).critical_gain_scale(m);
    Some(Boundaries {
        theorem1_product,
        exact_product,
        exact_certified,
    })
}
