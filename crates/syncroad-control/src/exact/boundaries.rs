//! The two stability boundaries of a delayed-driver scenario in the plane of a gain scale c
//! (A → cA) and a delay scale r (α → rα). Scaling changes `det(sI + diag(e^{−srα}) cL)` into
//! `det(zI + diag(e^{−zα}) crL)/r` with z = rs, so both boundaries are hyperbolas `c·r = const`:
//! Theorem 1 (1+) certifies below its constant, and the network is exactly stable below the
//! critical gain scale of the unscaled scenario.

use serde::Serialize;

use super::analysis::{network_matrices, uniform_ring};
use super::{acyclic_roots, critical_scale, CollocationOptions};
use crate::scenario::Model;
use crate::{theory, Scenario};

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
    let (exact_product, exact_certified) = match uniform_ring(sc, m) {
        Some(r) => (r.modes().ok().map(|x| x.critical_gain_scale), true),
        None => {
            let (a, d) = network_matrices(m);
            match acyclic_roots(&a, &d) {
                Ok(x) => (Some(x.critical_gain_scale), true),
                Err(_) => match critical_scale(&a, &d, &CollocationOptions::default()) {
                    Ok(c) => (Some(c.critical_gain_scale), c.certified),
                    Err(_) => (None, false),
                },
            }
        }
    };
    Some(Boundaries {
        theorem1_product,
        exact_product,
        exact_certified,
    })
}
