//! The paper's sufficient conditions, with per-vehicle margins and the binding vehicle named.
//!
//! * Theorem `thm.1` (via Theorem `thm.delay-agent`, the delayed driver being IFP(α_i) by
//!   Lemma `lem.delay-pass`): `G[A]` strongly connected and `α_j d_j^+ < 1/2`.
//! * Theorem `thm.1+`: additionally pinning gains, `α_j (d_j^+ + 2 b_j) < 1/2`, `Σ b_j > 0`.
//! * Theorem `thm.cacc`: `μ_i τ_i < 1/2` and the constants of eq. `constants-vehi`.
//! * Chandler's straight-road condition `2αK < 1` for uniform predecessor following.
//! * For the user's linear agents, Theorem `thm.1` / `thm.1+` with each agent's IFP index
//!   ([`crate::agents::index`]) in place of the delay: the same inequalities.
//!
//! Every report lists the agents with their indices ([`AgentReport`]).

use serde::Serialize;

use crate::agents::{self, Transfer};
use crate::graph::{Graph, GraphSummary};
use crate::ifp::cacc_agent_index;
use crate::scenario::{CaccModel, DelayedDriverModel, GraphShape, LinearModel, Model, Scenario};

/// The vehicle closest to violating a per-vehicle inequality `value < bound`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Binding {
    /// Vehicle index.
    pub vehicle: usize,
    /// The constrained quantity of that vehicle.
    pub value: f64,
    /// Its bound.
    pub bound: f64,
    /// `bound − value` (negative when violated).
    pub margin: f64,
}

fn binding(values: &[f64], bounds: &[f64]) -> Binding {
    let (vehicle, margin) = values
        .iter()
        .zip(bounds)
        .map(|(v, b)| b - v)
        .enumerate()
        .fold(
            (0, f64::INFINITY),
            |best, (i, m)| if m < best.1 { (i, m) } else { best },
        );
    Binding {
        vehicle,
        value: values[vehicle],
        bound: bounds[vehicle],
        margin,
    }
}

/// Theorem `thm.1` for the delayed-driver network.
#[derive(Debug, Clone, Serialize)]
pub struct Theorem1 {
    /// `G[A]` strongly connected.
    pub strongly_connected: bool,
    /// `α_j d_j^+` per vehicle.
    pub products: Vec<f64>,
    /// The vehicle with the largest `α_j d_j^+`.
    pub binding: Binding,
    /// Both conditions hold: synchronization is certified.
    pub holds: bool,
    /// Largest uniform scale `c` of all gains (A → cA) for which `α_j d_j^+ < 1/2` still holds:
    /// `1 / (2 max_j α_j d_j^+)` (∞ without delays).
    pub max_gain_scale: f64,
    /// Positive left null vector of the Laplacian (Lemma `lem.tech1`), for graphs small enough.
    pub left_null_vector: Option<Vec<f64>>,
}

/// Evaluates Theorem `thm.1` for IFP indices `alpha` (the delays, for delayed drivers).
pub fn theorem1(graph: &Graph, alpha: &[f64]) -> Theorem1 {
    let d = graph.in_degrees();
    let products: Vec<f64> = d.iter().zip(alpha).map(|(d, a)| d * a).collect();
    let bounds = vec![0.5; products.len()];
    let b = binding(&products, &bounds);
    let strongly_connected = graph.is_strongly_connected();
    let pmax = b.value;
    Theorem1 {
        strongly_connected,
        holds: strongly_connected && b.margin > 0.0,
        max_gain_scale: if pmax > 0.0 {
            0.5 / pmax
        } else {
            f64::INFINITY
        },
        left_null_vector: graph.left_null_vector().ok().flatten(),
        products,
        binding: b,
    }
}

/// Theorem `thm.1+` (reference tracking with pinning gains b_j).
#[derive(Debug, Clone, Serialize)]
pub struct Theorem1Plus {
    /// `G[A]` strongly connected.
    pub strongly_connected: bool,
    /// `Σ b_j`.
    pub pinning_sum: f64,
    /// `α_j (d_j^+ + 2 b_j)` per vehicle.
    pub products: Vec<f64>,
    /// The binding vehicle.
    pub binding: Binding,
    /// All conditions hold.
    pub holds: bool,
    /// Largest uniform scale of `(A, b)` keeping the inequality.
    pub max_gain_scale: f64,
}

/// Evaluates Theorem `thm.1+` for IFP indices `alpha` (delays for delayed drivers).
pub fn theorem1_plus(graph: &Graph, alpha: &[f64], pinning: &[f64]) -> Theorem1Plus {
    let d = graph.in_degrees();
    let products: Vec<f64> = (0..d.len())
        .map(|j| alpha[j] * (d[j] + 2.0 * pinning[j]))
        .collect();
    let b = binding(&products, &vec![0.5; products.len()]);
    let strongly_connected = graph.is_strongly_connected();
    let pinning_sum: f64 = pinning.iter().sum();
    Theorem1Plus {
        strongly_connected,
        pinning_sum,
        holds: strongly_connected && pinning_sum > 0.0 && b.margin > 0.0,
        max_gain_scale: if b.value > 0.0 {
            0.5 / b.value
        } else {
            f64::INFINITY
        },
        products,
        binding: b,
    }
}

/// Theorem `thm.cacc`.
#[derive(Debug, Clone, Serialize)]
pub struct CaccTheorem {
    /// `μ_i τ_i` per vehicle (must be < 1/2).
    pub mu_tau: Vec<f64>,
    /// Binding vehicle of `μ_i τ_i < 1/2`.
    pub lag_binding: Binding,
    /// Right-hand sides of eq. `constants-vehi` (2η_1+ν_1, η_i+ν_i, η_N).
    pub gain_sums: Vec<f64>,
    /// `μ_i²/2` per vehicle.
    pub half_mu_squared: Vec<f64>,
    /// Binding vehicle of eq. `constants-vehi` (value = gain sum, bound = μ²/2).
    pub gain_binding: Binding,
    /// IFP index of each agent `τ y''' + y'' + μ y' = u` by Lemma `lem.linear-pass` (= 1/μ² when μτ ≤ 1/2).
    pub ifp_index: Vec<f64>,
    /// Theorem `thm.1+` applied to the agents with those indices (the proof's route).
    pub via_theorem1_plus: Option<Theorem1Plus>,
    /// All conditions hold: the platoon reaches gaps s_i and speed v_0.
    pub holds: bool,
}

/// The graph and pinning gains the proof of Theorem `thm.cacc` builds:
/// `a_{i,i−1} = η_i`, `a_{i,i+1} = ν_i`, `b_1 = η_1`.
pub fn cacc_graph(m: &CaccModel) -> (Graph, Vec<f64>) {
    let n = m.mu.len();
    let mut arcs = Vec::new();
    for i in 0..n {
        if i > 0 {
            arcs.push(crate::graph::Arc {
                from: i - 1,
                to: i,
                weight: m.eta[i],
            });
        }
        if i + 1 < n && m.nu[i] > 0.0 {
            arcs.push(crate::graph::Arc {
                from: i + 1,
                to: i,
                weight: m.nu[i],
            });
        }
    }
    let mut b = vec![0.0; n];
    b[0] = m.eta[0];
    (
        Graph::from_arcs(n, &arcs).expect("CACC gains are validated positive"),
        b,
    )
}

/// Evaluates Theorem `thm.cacc`.
pub fn cacc_theorem(m: &CaccModel) -> CaccTheorem {
    let n = m.mu.len();
    let mu_tau: Vec<f64> = m.mu.iter().zip(&m.tau_s).map(|(a, b)| a * b).collect();
    let lag_binding = binding(&mu_tau, &vec![0.5; n]);
    let gain_sums: Vec<f64> = (0..n)
        .map(|i| {
            if n == 1 {
                // A single follower: only the leader term, b_1 = η_1 counted twice.
                2.0 * m.eta[0]
            } else if i == 0 {
                2.0 * m.eta[0] + m.nu[0]
            } else if i == n - 1 {
                m.eta[i]
            } else {
                m.eta[i] + m.nu[i]
            }
        })
        .collect();
    let half_mu_squared: Vec<f64> = m.mu.iter().map(|x| x * x / 2.0).collect();
    let gain_binding = binding(&gain_sums, &half_mu_squared);
    let ifp_index: Vec<f64> =
        m.mu.iter()
            .zip(&m.tau_s)
            .map(|(&mu, &tau)| {
                cacc_agent_index(mu, tau)
                    .map(|r| r.alpha)
                    .unwrap_or(f64::NAN)
            })
            .collect();
    let (graph, b) = cacc_graph(m);
    let via = (n > 1).then(|| theorem1_plus(&graph, &ifp_index, &b));
    CaccTheorem {
        holds: lag_binding.margin > 0.0 && gain_binding.margin > 0.0,
        mu_tau,
        lag_binding,
        gain_sums,
        half_mu_squared,
        gain_binding,
        ifp_index,
        via_theorem1_plus: via,
    }
}

/// Chandler's condition for uniform predecessor following.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Chandler {
    /// Uniform delay α [s].
    pub delay_s: f64,
    /// Uniform sensitivity K [1/s].
    pub gain: f64,
    /// `2αK`.
    pub two_alpha_k: f64,
    /// `2αK < 1`.
    pub holds: bool,
}

/// Chandler's straight-road condition `2αK < 1`, when the scenario is uniform predecessor
/// following (a chain behind a leader with b_0 = K, or a unidirectional ring).
pub fn chandler(scenario: &Scenario, m: &DelayedDriverModel) -> Option<Chandler> {
    let k = match m.shape {
        GraphShape::UnidirectionalRing { gain } => gain?,
        GraphShape::Chain { follower_gain } => {
            let k = if scenario.vehicles() > 1 {
                follower_gain?
            } else {
                m.leader.as_ref()?.1[0]
            };
            let (_, b) = m.leader.as_ref()?;
            if b[0] != k || b[1..].iter().any(|&x| x != 0.0) {
                return None;
            }
            k
        }
        _ => return None,
    };
    let a = m.delay_s[0];
    if m.delay_s.iter().any(|&x| x != a) {
        return None;
    }
    Some(Chandler {
        delay_s: a,
        gain: k,
        two_alpha_k: 2.0 * a * k,
        holds: 2.0 * a * k < 1.0,
    })
}

/// Everything `syncroad check` reports.
#[derive(Debug, Clone, Serialize)]
pub struct TheoryReport {
    /// Scenario name.
    pub scenario: String,
    /// Number of vehicles.
    pub vehicles: usize,
    /// Graph summary (delayed drivers; the proof's chain for CACC).
    pub graph: GraphSummary,
    /// Theorem `thm.1` (delayed drivers without leader).
    pub theorem1: Option<Theorem1>,
    /// Theorem `thm.1+` (delayed drivers with a leader).
    pub theorem1_plus: Option<Theorem1Plus>,
    /// Theorem `thm.cacc`.
    pub cacc: Option<CaccTheorem>,
    /// Chandler's `2αK < 1`.
    pub chandler: Option<Chandler>,
    /// Each driver's agent: its transfer and IFP index ([`crate::agents`]), the numbers
    /// Theorem 1 / 1+ weigh against the graph.
    pub agents: Vec<AgentReport>,
    /// Why the paper's theorems do not apply to this network, when an agent fails Lemma
    /// `lem.linear-pass`'s hypotheses (the agent and the hypothesis named).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_applicable: Option<String>,
    /// The sufficient conditions certify synchronization.
    pub certified: bool,
}

/// One driver's agent in the certificate.
#[derive(Debug, Clone, Serialize)]
pub struct AgentReport {
    /// `W = η/(sρ) · e^{−sτ}`.
    #[serde(flatten)]
    pub transfer: Transfer,
    /// The IFP index α_i the certificate uses (`None` when the agent fails the lemma).
    pub ifp_index: Option<f64>,
    /// The index is exact; otherwise a rigorous upper bound.
    pub exact: Option<bool>,
    /// A lower bound of the true index.
    pub lower_bound: Option<f64>,
    /// What the index rests on.
    pub rests_on: Option<&'static str>,
    /// The hypothesis the agent fails, when it has no index.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hypothesis_failed: Option<String>,
}

/// The agents of a model with their indices; identical agents are computed once.
pub fn agent_reports(model: &Model) -> Vec<AgentReport> {
    let mut seen: Vec<(Transfer, AgentReport)> = Vec::new();
    model
        .transfers()
        .into_iter()
        .map(|t| {
            if let Some((_, r)) = seen.iter().rev().find(|(u, _)| *u == t) {
                return r.clone();
            }
            let r = match agents::index(&t) {
                Ok(i) => AgentReport {
                    transfer: t.clone(),
                    ifp_index: Some(i.ifp_index),
                    exact: Some(i.exact),
                    lower_bound: Some(i.lower_bound),
                    rests_on: Some(i.method.rests_on()),
                    hypothesis_failed: None,
                },
                Err(e) => AgentReport {
                    transfer: t.clone(),
                    ifp_index: None,
                    exact: None,
                    lower_bound: None,
                    rests_on: None,
                    hypothesis_failed: Some(e.to_string()),
                },
            };
            if seen.len() > 64 {
                seen.remove(0);
            }
            seen.push((t, r.clone()));
            r
        })
        .collect()
}

/// Theorem 1 / 1+ for the user's linear agents: their indices on the graph.
fn linear_report(scenario: &Scenario, m: &LinearModel) -> TheoryReport {
    let agents = agent_reports(scenario.model());
    let failed = agents
        .iter()
        .enumerate()
        .find_map(|(i, a)| a.hypothesis_failed.as_ref().map(|h| (i, h)));
    let not_applicable = failed.map(|(i, h)| {
        format!("agent {i} (model.agents[{i}]) is not IFP by Lemma lem.linear-pass: {h}; Theorems 1 and 1+ need every agent IFP. `syncroad stability` still gives the exact answer")
    });
    let alpha: Vec<f64> = agents
        .iter()
        .map(|a| a.ifp_index.unwrap_or(f64::NAN))
        .collect();
    let (t1, t1p) = if not_applicable.is_some() {
        (None, None)
    } else {
        match &m.leader {
            None => (Some(theorem1(&m.graph, &alpha)), None),
            Some((_, b)) => (None, Some(theorem1_plus(&m.graph, &alpha, b))),
        }
    };
    let certified = t1.as_ref().is_some_and(|t| t.holds) || t1p.as_ref().is_some_and(|t| t.holds);
    TheoryReport {
        scenario: scenario.name().to_string(),
        vehicles: scenario.vehicles(),
        graph: GraphSummary::from(&m.graph),
        theorem1: t1,
        theorem1_plus: t1p,
        cacc: None,
        chandler: None,
        agents,
        not_applicable,
        certified,
    }
}

/// Evaluates every condition that applies to the scenario.
pub fn report(scenario: &Scenario) -> TheoryReport {
    if scenario.vehicles() == 0 {
        // Only an inflow's vehicles, which come and go: no fixed network to certify.
        return TheoryReport {
            scenario: scenario.name().to_string(),
            vehicles: 0,
            graph: GraphSummary {
                vehicles: 0,
                arcs: 0,
                strongly_connected: false,
                spanning_tree_root: None,
            },
            theorem1: None,
            theorem1_plus: None,
            cacc: None,
            chandler: None,
            agents: Vec::new(),
            not_applicable: None,
            certified: false,
        };
    }
    match scenario.model() {
        Model::DelayedDriver(m) => {
            let (t1, t1p) = match &m.leader {
                None => (Some(theorem1(&m.graph, &m.delay_s)), None),
                Some((_, b)) => (None, Some(theorem1_plus(&m.graph, &m.delay_s, b))),
            };
            let ch = chandler(scenario, m);
            // Chandler's 2αK < 1 certifies uniform predecessor following even where the chain
            // is not strongly connected (each mode s + K e^{−sα} = 0 is then stable).
            let certified = t1.as_ref().is_some_and(|t| t.holds)
                || t1p.as_ref().is_some_and(|t| t.holds)
                || ch.is_some_and(|c| c.holds);
            TheoryReport {
                scenario: scenario.name().to_string(),
                vehicles: scenario.vehicles(),
                graph: GraphSummary::from(&m.graph),
                theorem1: t1,
                theorem1_plus: t1p,
                cacc: None,
                chandler: ch,
                agents: agent_reports(scenario.model()),
                not_applicable: None,
                certified,
            }
        }
        Model::Cacc(c) => {
            let t = cacc_theorem(c);
            TheoryReport {
                scenario: scenario.name().to_string(),
                vehicles: scenario.vehicles(),
                graph: GraphSummary::from(&cacc_graph(c).0),
                theorem1: None,
                theorem1_plus: None,
                certified: t.holds,
                cacc: Some(t),
                chandler: None,
                agents: agent_reports(scenario.model()),
                not_applicable: None,
            }
        }
        Model::Linear(m) => linear_report(scenario, m),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::LeaderProfile;
    use approx::assert_relative_eq;

    #[test]
    fn theorem1_names_the_binding_driver_and_the_gain_scale() {
        let g = Graph::unidirectional_ring(4, &[0.5, 0.5, 1.0, 0.5]).unwrap();
        let t = theorem1(&g, &[0.4, 0.4, 0.45, 0.4]);
        assert!(t.holds);
        assert_eq!(t.binding.vehicle, 2);
        assert_relative_eq!(t.binding.value, 0.45);
        assert_relative_eq!(t.max_gain_scale, 0.5 / 0.45);
        // Scaling beyond c breaks it, below keeps it.
        assert!(!theorem1(&g.scaled(t.max_gain_scale * 1.001), &[0.4, 0.4, 0.45, 0.4]).holds);
        assert!(theorem1(&g.scaled(t.max_gain_scale * 0.999), &[0.4, 0.4, 0.45, 0.4]).holds);
    }

    #[test]
    fn theorem1_needs_strong_connectivity() {
        let g = Graph::chain(3, &[0.0, 0.1, 0.1]).unwrap();
        let t = theorem1(&g, &[0.1; 3]);
        assert!(!t.strongly_connected && !t.holds);
    }

    #[test]
    fn cacc_constants_imply_theorem1_plus_as_the_proof_says() {
        // "A straightforward computation shows that (constants-vehi) implies (degree1+)": with
        // α_i = 1/μ_i² the two per-vehicle margins are the same inequality scaled by 2/μ_i².
        let m = CaccModel {
            mu: vec![1.0, 1.2, 0.9, 1.1],
            eta: vec![0.1, 0.2, 0.15, 0.3],
            nu: vec![0.2, 0.3, 0.1, 0.0],
            desired_gap_m: vec![10.0; 4],
            tau_s: vec![0.3, 0.2, 0.4, 0.1],
            length_m: vec![5.0; 4],
            leader: LeaderProfile::Constant { speed_mps: 20.0 },
        };
        let t = cacc_theorem(&m);
        assert!(t.holds);
        let via = t.via_theorem1_plus.as_ref().unwrap();
        assert!(via.holds);
        for i in 0..4 {
            assert_relative_eq!(
                t.ifp_index[i],
                1.0 / (m.mu[i] * m.mu[i]),
                max_relative = 1e-12
            );
            assert_relative_eq!(
                via.products[i],
                t.gain_sums[i] / (m.mu[i] * m.mu[i]),
                max_relative = 1e-12
            );
        }
        // Violating eq. constants-vehi at vehicle 2 names it.
        let mut bad = m.clone();
        bad.eta[2] = 1.0;
        let t = cacc_theorem(&bad);
        assert!(!t.holds);
        assert_eq!(t.gain_binding.vehicle, 2);
    }
}
