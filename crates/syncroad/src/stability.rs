//! `syncroad stability`: exact stability next to the paper's sufficient conditions.
//!
//! * Delayed drivers: rightmost characteristic roots of `det(sI + diag(e^{−sα_i}) L) = 0`
//!   (roots other than consensus), the critical scale of all gains and of all delays, and the
//!   conservatism ratio against Theorem 1. Uniform rings of any size use the Fourier/Lambert-W
//!   fast path; other graphs the full solve (collocation + Newton, certified by the argument
//!   principle). A leader with pinning gains enters as an extra, undelayed vertex whose speed
//!   never changes, so the consensus root is the leader's own mode.
//! * CACC platoons: closed-loop eigenvalues, Theorem `thm.cacc` beside the exact verdict, and
//!   string stability.

use std::fmt::Write as _;

use nalgebra::DMatrix;
use serde::Serialize;
use syncroad_control::exact::{
    self, AcyclicReport, CaccParams, CaccReport, CollocationOptions, NetworkStabilityReport,
    RingModes, StringStabilityOptions, UniformRing,
};
use syncroad_control::scenario::{DelayedDriverModel, GraphSpec, ModelSpec};
use syncroad_control::theory::{self, TheoryReport};
use syncroad_control::{scenario::Model, Scenario};

use crate::error::InputError;

/// Largest network (vehicles, leader included) for the full root solve.
pub const FULL_SOLVE_LIMIT: usize = 150;

/// Everything `syncroad stability` reports.
#[derive(Debug, Clone, Serialize)]
pub struct StabilityReport {
    /// Scenario name.
    pub scenario: String,
    /// The paper's conditions.
    pub paper: TheoryReport,
    /// Uniform-ring fast path, when the scenario is a uniform ring.
    pub ring: Option<RingModes>,
    /// Exact per-driver roots, when the network is acyclic (a chain behind a leader).
    pub acyclic: Option<AcyclicReport>,
    /// Full solve of the network, when small enough and not acyclic.
    pub network: Option<NetworkStabilityReport>,
    /// CACC platoon analysis.
    pub cacc: Option<CaccReport>,
    /// Exact verdict: synchronization (all non-consensus roots in Re s < 0).
    pub exactly_stable: bool,
    /// The paper's conditions certify it.
    pub certified: bool,
}

/// The uniform ring described by the scenario, if it is one.
pub fn uniform_ring(sc: &Scenario, m: &DelayedDriverModel) -> Option<UniformRing> {
    let ModelSpec::DelayedDriver { graph, .. } = &sc.file.model else {
        return None;
    };
    let a = m.delay_s[0];
    if m.leader.is_some() || m.delay_s.iter().any(|x| *x != a) {
        return None;
    }
    let (kf, kb) = match graph {
        GraphSpec::UnidirectionalRing { gain } => (gain.uniform_value(0)?, 0.0),
        GraphSpec::BidirectionalRing {
            gain_pred,
            gain_follow,
        } => (gain_pred.uniform_value(0)?, gain_follow.uniform_value(0)?),
        _ => return None,
    };
    UniformRing::new(sc.n, kf, kb, a).ok()
}

/// Adjacency and delays of the network, the leader appended as an undelayed vertex.
pub fn network_matrices(m: &DelayedDriverModel) -> (DMatrix<f64>, Vec<f64>) {
    let n = m.graph.len();
    match &m.leader {
        None => (m.graph.adjacency_dense(), m.delay_s.clone()),
        Some((_, b)) => {
            let mut a = DMatrix::zeros(n + 1, n + 1);
            a.view_mut((0, 0), (n, n))
                .copy_from(&m.graph.adjacency_dense());
            for (i, bi) in b.iter().enumerate() {
                a[(i, n)] = *bi;
            }
            let mut d = m.delay_s.clone();
            d.push(0.0);
            (a, d)
        }
    }
}

/// Runs the analysis.
pub fn analyse(sc: &Scenario) -> anyhow::Result<StabilityReport> {
    let paper = theory::report(sc);
    match &sc.model {
        Model::DelayedDriver(m) => {
            let ring = match uniform_ring(sc, m) {
                Some(r) => Some(r.modes()?),
                None => None,
            };
            let size = m.graph.len() + usize::from(m.leader.is_some());
            let (a, d) = network_matrices(m);
            let acyclic = exact::acyclic_roots(&a, &d).ok();
            let network = if acyclic.is_some() {
                None
            } else if size <= FULL_SOLVE_LIMIT {
                Some(exact::analyse_network(
                    &a,
                    &d,
                    &CollocationOptions::default(),
                    true,
                )?)
            } else if ring.is_none() {
                return Err(InputError::new(format!(
                    "the scenario has {size} vehicles: the full root solve is limited to {FULL_SOLVE_LIMIT}; \
                     uniform rings of any size use the Fourier fast path (uniform gains and delays)"
                ))
                .into());
            } else {
                None
            };
            let exactly_stable = match (&acyclic, &network, &ring) {
                (Some(x), _, _) => x.abscissa < 0.0,
                (None, Some(n), _) => n.roots.is_stable(),
                (None, None, Some(r)) => r.abscissa < 0.0,
                (None, None, None) => unreachable!("one of the three is computed"),
            };
            Ok(StabilityReport {
                scenario: sc.name.clone(),
                certified: paper.certified,
                paper,
                ring,
                acyclic,
                network,
                cacc: None,
                exactly_stable,
            })
        }
        Model::Cacc(c) => {
            let params = CaccParams {
                tau_s: c.tau_s.clone(),
                mu: c.mu.clone(),
                eta: c.eta.clone(),
                nu: c.nu[..c.nu.len().saturating_sub(1)].to_vec(),
            };
            let r = exact::analyse_cacc(&params, &StringStabilityOptions::default())?;
            Ok(StabilityReport {
                scenario: sc.name.clone(),
                certified: paper.certified,
                paper,
                ring: None,
                acyclic: None,
                network: None,
                exactly_stable: r.modes.exactly_stable,
                cacc: Some(r),
            })
        }
    }
}

/// The table printed by `syncroad stability`.
pub fn table(r: &StabilityReport) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "scenario {}: exact stability", r.scenario);
    if let Some(ring) = &r.ring {
        let _ = writeln!(s, "\nuniform ring, Fourier modes (Lambert W fast path):");
        let _ = write!(s, "{ring}");
    }
    if let Some(x) = &r.acyclic {
        let _ = writeln!(
            s,
            "\nacyclic network: det = Π_i (s + d_i e^(−sα_i)), exact roots by Lambert W:"
        );
        let _ = writeln!(
            s,
            "{:>7} {:>10} {:>10} {:>14} {:>14}",
            "driver", "d_i [1/s]", "α_i [s]", "Re s [1/s]", "Im s [rad/s]"
        );
        for d in x.drivers.iter().take(30) {
            let _ = writeln!(
                s,
                "{:>7} {:>10.4} {:>10.4} {:>14.6e} {:>14.6e}",
                d.driver, d.gain, d.delay_s, d.re, d.im
            );
        }
        if x.drivers.len() > 30 {
            let _ = writeln!(s, "    ... {} more drivers", x.drivers.len() - 30);
        }
        let _ = writeln!(
            s,
            "spectral abscissa {:.6e} 1/s (driver {})",
            x.abscissa, x.dominant_driver
        );
        let t1 = r.paper.theorem1_plus.as_ref().map(|t| t.max_gain_scale);
        let _ = writeln!(
            s,
            "critical gain scale {:.10} (min_i π/(2 α_i d_i)){}",
            x.critical_gain_scale,
            t1.map_or(String::new(), |t| format!(
                "  Theorem-1+ {t:.10}  ratio {:.6}",
                x.critical_gain_scale / t
            ))
        );
    }
    if let Some(n) = &r.network {
        let _ = writeln!(s, "\nfull solve (Chebyshev collocation + Newton):");
        let _ = write!(s, "{n}");
    }
    if let Some(c) = &r.cacc {
        let _ = writeln!(s, "\nCACC platoon:");
        let _ = write!(s, "{c}");
    }
    let _ = writeln!(
        s,
        "\nexact: {}   paper's conditions: {}",
        if r.exactly_stable {
            "SYNCHRONIZES"
        } else {
            "does NOT synchronize"
        },
        if r.certified {
            "certified"
        } else {
            "not certified"
        }
    );
    if r.certified && !r.exactly_stable {
        let _ = writeln!(s, "WARNING: the sufficient conditions certify a network the exact analysis finds unstable; please report this scenario.");
    }
    s
}
