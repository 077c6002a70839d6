//! Exact stability of a whole scenario: the method chosen for its structure, and one verdict.
//!
//! * Uniform rings (equal gains and delays, no leader): Fourier modes and Lambert W, any `N`
//!   ([`super::ring_modes`]).
//! * Acyclic networks (chains behind a leader): exact per-driver roots ([`super::acyclic`]),
//!   and the string-stability peak of every predecessor-to-follower transfer
//!   ([`super::string_stability::chandler_string_peak`]).
//! * Any other graph up to [`NETWORK_SOLVE_LIMIT`] vehicles: collocation and Newton (the
//!   collocation's rightmost eigenvalues by shift-invert Arnoldi, its dense Schur form up to
//!   [`FULL_SOLVE_LIMIT`] when that is not certified), certified by the argument principle,
//!   and the critical scale by continuation ([`super::report::analyse_network`]).
//! * With a leader, when the network synchronizes: the worst amplification from the leader's
//!   speed to a follower's ([`super::leader_amplification`]).
//! * CACC platoons: closed-loop eigenvalues and string stability ([`super::report::analyse_cacc`]).
//!
//! A leader with pinning gains enters as an extra, undelayed vertex whose speed never changes,
//! so the consensus root is the leader's own mode.

use nalgebra::DMatrix;
use serde::Serialize;

use super::acyclic::{acyclic_roots, AcyclicReport};
use super::cacc_modes::CaccParams;
use super::collocation::CollocationOptions;
use super::leader_amplification::{leader_amplification, LeaderAmplification};
use super::platoon_scaling::{platoon_scaling, PlatoonLaw, PlatoonScaling, PlatoonScalingError};
use super::report::{
    analyse_cacc, analyse_network_reporting, CaccReport, NetworkStabilityReport, ReportError,
};
use super::ring_modes::{RingError, RingModes, UniformRing};
use super::string_stability::{chandler_string_peak, StringStabilityOptions};
use crate::scenario::Scenario;
use crate::scenario::{CaccModel, DelayedDriverModel, GraphShape, LinearModel, Model};
use crate::theory::{self, TheoryReport};

/// Largest network (vehicles, leader included) for the dense collocation solve
/// ([`super::rightmost_roots`]): `map` at every grid point, and the fallback of the
/// shift-invert solve.
pub const FULL_SOLVE_LIMIT: usize = super::report::DENSE_SOLVE_LIMIT;

/// Largest network (vehicles, leader included) that [`analyse`] solves for its roots: by
/// shift-invert Arnoldi and band LUs ([`super::rightmost_roots_shift_invert`]), certified by
/// root counts; about 2 s for a heterogeneous ring of 200.
pub const NETWORK_SOLVE_LIMIT: usize = 400;

/// Failure of the scenario analysis.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AnalysisError {
    /// Too many vehicles for the root solve, and no fast path applies.
    #[error("the scenario has {vehicles} vehicles (field `vehicles`, leader included): the root solve of a general network is limited to {limit}; uniform rings of any size use the Fourier fast path (one value for every gain in `model.graph` and for `model.delay_s`), chains behind a leader the exact per-driver roots")]
    TooLargeForFullSolve {
        /// Vehicles, leader included.
        vehicles: usize,
        /// [`NETWORK_SOLVE_LIMIT`].
        limit: usize,
    },
    /// The uniform-ring fast path failed.
    #[error("uniform ring (Fourier modes)")]
    Ring(#[source] RingError),
    /// The full solve of the delayed-driver network failed.
    #[error("delayed-driver network (model.graph, model.delay_s)")]
    Network(#[source] ReportError),
    /// The CACC analysis failed.
    #[error("CACC platoon (model.mu, model.eta, model.nu, model.tau_s)")]
    Cacc(#[source] ReportError),
    /// The platoon-scaling study failed.
    #[error("platoon scaling")]
    PlatoonScaling(#[source] PlatoonScalingError),
    /// Every gain × delay of the network is so small that its characteristic roots lie within
    /// the searches' tolerances of the origin (gains of 1e-200 once made the search run without
    /// end; gains near 1e-11 made the root-count certificate fail on a spurious root).
    #[error("the largest gain × delay of the network (model.graph, model.delay_s) is {gain_delay:.3e}: its characteristic roots lie within the root searches' tolerances of s = 0, where no root count can be trusted; exact analysis needs a largest gain × delay of at least {MIN_GAIN_DELAY:e}; at such gains the paper's conditions decide (`syncroad check`)")]
    BelowResolution {
        /// `max_i α_i Σ_j a_ij`.
        gain_delay: f64,
    },
    /// Gains so large that the root searches lose the roots (their real parts grow like
    /// `ln(gain × delay)/delay`, beyond the contours the counts can close).
    #[error("the largest gain × delay of the network (model.graph, model.delay_s) is {gain_delay:.3e}: beyond {MAX_GAIN_DELAY:e} the root searches lose the characteristic roots; exact analysis takes a largest gain × delay of at most {MAX_GAIN_DELAY:e} (the native simulator runs such a network: `syncroad simulate`)")]
    AboveResolution {
        /// `max_i α_i Σ_j a_ij`.
        gain_delay: f64,
    },
    /// A network of one driver.
    #[error("{}", too_few(*vehicles))]
    TooFewVehicles {
        /// Vehicles, the leader included.
        vehicles: usize,
    },
    /// The linear agents' analysis failed or does not apply.
    #[error("linear agents (model.agents)")]
    Linear(#[source] super::linear::LinearAnalysisError),
    /// Platoon scaling was asked for a model that is not a CACC platoon.
    #[error("platoon scaling needs a CACC platoon (model.type = \"cacc\")")]
    PlatoonScalingNeedsCacc,
}

/// Why a network of `vehicles` (fewer than 2) has no exact analysis.
fn too_few(vehicles: usize) -> String {
    if vehicles == 0 {
        return "the scenario has no vehicles of its own (\"vehicles\": 0, an open road of inflows): there is no network to analyse; `syncroad run` measures its traffic".to_string();
    }
    format!("the scenario has {vehicles} vehicle (field `vehicles`, leader included): exact stability analyses a network of at least 2 (a lone driver has nobody to synchronize with; `syncroad check` and `simulate` take it)")
}

/// The smallest largest gain × delay the exact analysis takes. The roots scale with the gains,
/// and the root counts and searches work to absolute tolerances near 1e-11 /s: on the
/// heterogeneous 50-vehicle rings the root-count certificate failed from 1e-10 down (a
/// spurious root on the contour) while 1e-9 was still right, so the limit keeps a factor 100.
/// At 1e-8 the slowest mode's time constant is about three years.
pub const MIN_GAIN_DELAY: f64 = 1e-8;

/// The largest largest gain × delay the exact analysis takes: `ring-theorem1` with its gains
/// scaled by 10⁴ (gain × delay 4.9e3) is analysed, by 10⁵ (4.9e4) its roots are lost.
pub const MAX_GAIN_DELAY: f64 = 1e4;

/// `max_i α_i (Σ_j a_ij + b_i)`: the largest gain × delay of a delayed-driver network, the
/// scale of its characteristic roots.
pub fn max_gain_delay(m: &DelayedDriverModel) -> f64 {
    let leader = m.leader.as_ref().map(|(_, b)| b.as_slice());
    (0..m.graph.len())
        .map(|i| {
            let b = leader.map_or(0.0, |b| b[i]);
            m.delay_s[i] * (m.graph.in_degree(i) + b)
        })
        .fold(0.0, f64::max)
}

/// True when the network's roots lie within round-off of the origin (positive largest gain ×
/// delay below [`MIN_GAIN_DELAY`]): no root search or count can be trusted there, and the
/// searches would run without end.
pub fn below_resolution(m: &DelayedDriverModel) -> bool {
    let g = max_gain_delay(m);
    g > 0.0 && g < MIN_GAIN_DELAY
}

/// The exact verdict.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ExactVerdict {
    /// Every non-consensus root has `Re s < 0` (certified where a certificate applies).
    Synchronizes,
    /// Some non-consensus root has `Re s ≥ 0`.
    DoesNotSynchronize,
    /// The argument-principle count disagrees with the computed roots: roots may have been
    /// missed, so no verdict is given.
    Uncertified,
}

/// Whether the critical scale a report prints is backed by a certificate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CriticalScaleStatus {
    /// A closed form: the uniform ring's modes or the acyclic network's per-driver roots.
    ClosedForm,
    /// Found by a search and certified by root counts at `c*`.
    Certified,
    /// Found by a search whose root counts at `c*` do not confirm it: another root may cross
    /// first. Reported as UNCERTIFIED, and `stability` exits 1.
    Uncertified,
    /// No critical scale (no delays, or a CACC platoon).
    None,
}

/// String stability of a chain behind a leader (acyclic network).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ChainStringStability {
    /// Per driver with a single predecessor: `sup_ω |H_i(iω)|` of
    /// `H_i = d_i e^{−sα_i}/(s + d_i e^{−sα_i})` (∞ if the driver is unstable).
    pub peaks: Vec<DriverPeak>,
    /// The largest peak: the worst amplification from one vehicle to the next.
    pub worst_peak: f64,
    /// The driver attaining it.
    pub worst_driver: usize,
    /// Chandler's boundary: `max_i 2 α_i d_i` (string stable iff ≤ 1).
    pub max_two_alpha_d: f64,
    /// Every peak ≤ 1 (to 1e-12).
    pub string_stable: bool,
}

/// String-stability peak of one driver.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DriverPeak {
    /// Driver index.
    pub driver: usize,
    /// `2 α_i d_i` (Chandler's `2αK`).
    pub two_alpha_d: f64,
    /// `sup_ω |H_i(iω)|`.
    pub peak: f64,
}

/// A network whose graph has no directed spanning tree: the consensus root `s = 0` is
/// multiple, one per source component, and each component keeps its own speed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NoSpanningTree {
    /// A vehicle that no single vehicle reaches through the graph (the leader, when there is
    /// one, is vehicle N).
    pub unreached: usize,
    /// Multiplicity of the root `s = 0`: the number of groups of vehicles that no vehicle
    /// outside the group influences ([`crate::graph::Graph::source_components`]).
    pub consensus_multiplicity: usize,
}

/// The full solve of a network, by kind of agent; both give `roots.abscissa` and
/// `critical.critical_gain_scale`.
#[derive(Debug, Clone, Serialize)]
#[serde(untagged)]
pub enum NetworkReport {
    /// Delayed drivers: collocation, Newton, root counts, continuation.
    Delayed(NetworkStabilityReport),
    /// Delay-free rational agents: closed-loop eigenvalues and root counts.
    Linear(super::linear::LinearNetworkReport),
}

impl NetworkReport {
    /// The delayed drivers' report.
    pub fn delayed(&self) -> Option<&NetworkStabilityReport> {
        match self {
            NetworkReport::Delayed(n) => Some(n),
            NetworkReport::Linear(_) => None,
        }
    }

    /// The linear agents' report.
    pub fn linear(&self) -> Option<&super::linear::LinearNetworkReport> {
        match self {
            NetworkReport::Linear(n) => Some(n),
            NetworkReport::Delayed(_) => None,
        }
    }
}

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
    /// String stability of an acyclic chain.
    pub chain_string_stability: Option<ChainStringStability>,
    /// With a leader and a synchronizing network (chains, heterogeneous or not, and graphs
    /// with cycles such as bidirectional platoons): the peak gain from the leader's speed to
    /// each follower's, and the worst along the platoon.
    pub leader_amplification: Option<LeaderAmplification>,
    /// Full solve of the network, when small enough and not acyclic: the delayed drivers'
    /// roots and critical scale, or the linear agents' ([`super::linear`]).
    pub network: Option<NetworkReport>,
    /// CACC platoon analysis.
    pub cacc: Option<CaccReport>,
    /// The exact verdict.
    pub verdict: ExactVerdict,
    /// `verdict == Synchronizes`.
    pub exactly_stable: bool,
    /// Whether the critical scale printed is certified.
    pub critical_scale_status: CriticalScaleStatus,
    /// Set when the graph has no directed spanning tree: the velocities cannot synchronize,
    /// whatever the roots off zero, and no other analysis is made.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub no_spanning_tree: Option<NoSpanningTree>,
    /// The paper's conditions certify it.
    pub certified: bool,
}

/// The uniform ring described by the scenario, if it is one.
pub fn uniform_ring(sc: &Scenario, m: &DelayedDriverModel) -> Option<UniformRing> {
    let a = m.delay_s[0];
    if m.leader.is_some() || m.delay_s.iter().any(|x| *x != a) {
        return None;
    }
    let (kf, kb) = match m.shape {
        GraphShape::UnidirectionalRing { gain } => (gain?, 0.0),
        GraphShape::BidirectionalRing {
            gain_pred,
            gain_follow,
        } => (gain_pred?, gain_follow?),
        _ => return None,
    };
    UniformRing::new(sc.vehicles(), kf, kb, a).ok()
}

/// Adjacency and delays of the network, the leader appended as an undelayed vertex.
pub fn network_matrices(m: &DelayedDriverModel) -> (DMatrix<f64>, Vec<f64>) {
    let mut d = m.delay_s.clone();
    if m.leader.is_some() {
        d.push(0.0);
    }
    (with_leader(&m.graph, m.leader.as_ref()), d)
}

/// The adjacency of `graph`, with the leader appended as vertex N when there is one (column N
/// holds the pinning gains `b_i`).
fn with_leader(graph: &crate::graph::Graph, leader: Option<&(f64, Vec<f64>)>) -> DMatrix<f64> {
    let n = graph.len();
    let Some((_, b)) = leader else {
        return graph.adjacency_dense();
    };
    let mut a = DMatrix::zeros(n + 1, n + 1);
    a.view_mut((0, 0), (n, n))
        .copy_from(&graph.adjacency_dense());
    for (i, bi) in b.iter().enumerate() {
        a[(i, n)] = *bi;
    }
    a
}

/// Peaks of the predecessor-to-follower transfers of an acyclic network: for each driver that
/// observes exactly one vehicle, `chandler_string_peak(α_i d_i)`.
fn chain_string_stability(a: &DMatrix<f64>, d: &[f64]) -> Option<ChainStringStability> {
    let n = a.nrows();
    let mut peaks = Vec::new();
    for i in 0..n {
        let arcs = (0..n).filter(|&j| a[(i, j)] > 0.0).count();
        if arcs != 1 || d[i] == 0.0 {
            continue;
        }
        let di: f64 = a.row(i).sum();
        peaks.push(DriverPeak {
            driver: i,
            two_alpha_d: 2.0 * d[i] * di,
            peak: chandler_string_peak(d[i] * di),
        });
    }
    let worst = peaks.iter().max_by(|x, y| x.peak.total_cmp(&y.peak))?;
    Some(ChainStringStability {
        worst_peak: worst.peak,
        worst_driver: worst.driver,
        max_two_alpha_d: peaks.iter().map(|p| p.two_alpha_d).fold(0.0, f64::max),
        string_stable: peaks.iter().all(|p| p.peak <= 1.0 + 1e-12),
        peaks,
    })
}

impl StabilityReport {
    /// The report of a network without a directed spanning tree: nothing else is analysed.
    fn unsynchronizable(sc: &Scenario, paper: TheoryReport, gap: NoSpanningTree) -> Self {
        Self {
            scenario: sc.name().to_string(),
            certified: paper.certified,
            critical_scale_status: CriticalScaleStatus::None,
            paper,
            ring: None,
            acyclic: None,
            chain_string_stability: None,
            leader_amplification: None,
            network: None,
            cacc: None,
            exactly_stable: false,
            verdict: ExactVerdict::DoesNotSynchronize,
            no_spanning_tree: Some(gap),
        }
    }
}

/// `Some` when the network (adjacency `a`, leader included) has no directed spanning tree.
fn no_spanning_tree(a: &DMatrix<f64>) -> Option<NoSpanningTree> {
    let graph = crate::graph::Graph::from_dense(a).ok()?;
    graph.spanning_tree_gap().map(|unreached| NoSpanningTree {
        unreached,
        consensus_multiplicity: graph.source_components(),
    })
}

/// Runs the exact analysis of a scenario.
///
/// # Errors
/// [`AnalysisError`]: a network too large for the full solve without a fast path, or a
/// failed computation (with its cause).
pub fn analyse(sc: &Scenario) -> Result<StabilityReport, AnalysisError> {
    analyse_reporting(sc, &|_| {})
}

/// [`analyse`], naming each step to `on_step` as it starts (the rightmost roots with their
/// root-count certificate, then the critical scale), for a progress display.
///
/// # Errors
/// As [`analyse`].
pub fn analyse_reporting(
    sc: &Scenario,
    on_step: &(dyn Fn(&'static str) + Sync),
) -> Result<StabilityReport, AnalysisError> {
    let paper = theory::report(sc);
    match sc.model() {
        Model::DelayedDriver(m) => analyse_delayed(sc, m, paper, on_step),
        Model::Linear(m) => analyse_linear_scenario(sc, m, paper, on_step),
        Model::Cacc(c) => {
            let params = cacc_params(c);
            let r = analyse_cacc(&params, &StringStabilityOptions::default())
                .map_err(AnalysisError::Cacc)?;
            let verdict = if r.modes.exactly_stable {
                ExactVerdict::Synchronizes
            } else {
                ExactVerdict::DoesNotSynchronize
            };
            Ok(StabilityReport {
                scenario: sc.name().to_string(),
                certified: paper.certified,
                paper,
                ring: None,
                acyclic: None,
                chain_string_stability: None,
                leader_amplification: None,
                network: None,
                exactly_stable: verdict == ExactVerdict::Synchronizes,
                critical_scale_status: CriticalScaleStatus::None,
                verdict,
                cacc: Some(r),
                no_spanning_tree: None,
            })
        }
    }
}

/// The delayed-driver network `m` (the scenario's, or its linear agents when they are all
/// delayed integrators) against the conditions `paper`.
fn analyse_delayed(
    sc: &Scenario,
    m: &DelayedDriverModel,
    paper: TheoryReport,
    on_step: &(dyn Fn(&'static str) + Sync),
) -> Result<StabilityReport, AnalysisError> {
    let gain_delay = max_gain_delay(m);
    if below_resolution(m) {
        return Err(AnalysisError::BelowResolution { gain_delay });
    }
    if gain_delay > MAX_GAIN_DELAY {
        return Err(AnalysisError::AboveResolution { gain_delay });
    }
    let vehicles = m.graph.len() + usize::from(m.leader.is_some());
    if vehicles < 2 {
        return Err(AnalysisError::TooFewVehicles { vehicles });
    }
    let ring = match uniform_ring(sc, m) {
        Some(r) => Some(r.modes().map_err(AnalysisError::Ring)?),
        None => None,
    };
    let size = m.graph.len() + usize::from(m.leader.is_some());
    let (a, d) = network_matrices(m);
    // Consensus needs the root s = 0 to be simple: checked before any path, since
    // each (the acyclic factors above all) reads its roots off zero only.
    if let Some(gap) = no_spanning_tree(&a) {
        return Ok(StabilityReport::unsynchronizable(sc, paper, gap));
    }
    let acyclic = acyclic_roots(&a, &d).ok();
    let network = if acyclic.is_some() {
        None
    } else if size <= NETWORK_SOLVE_LIMIT {
        Some(
            analyse_network_reporting(&a, &d, &CollocationOptions::default(), on_step)
                .map_err(AnalysisError::Network)?,
        )
    } else if ring.is_none() {
        return Err(AnalysisError::TooLargeForFullSolve {
            vehicles: size,
            limit: NETWORK_SOLVE_LIMIT,
        });
    } else {
        None
    };
    let stable = |s: bool| {
        if s {
            ExactVerdict::Synchronizes
        } else {
            ExactVerdict::DoesNotSynchronize
        }
    };
    let verdict = match (&acyclic, &network, &ring) {
        (Some(x), _, _) => stable(x.abscissa < 0.0),
        (None, Some(n), _) => match n.certified_stability() {
            Some(s) => stable(s),
            None => ExactVerdict::Uncertified,
        },
        (None, None, Some(r)) => stable(r.abscissa < 0.0),
        (None, None, None) => unreachable!("one of the three is computed"),
    };
    let chain_string_stability = acyclic
        .as_ref()
        .and_then(|_| chain_string_stability(&a, &d));
    let leader_amplification = match (&m.leader, verdict) {
        (Some(_), ExactVerdict::Synchronizes) => {
            let frequencies: Vec<f64> = match (&acyclic, &network) {
                (Some(x), _) => x.drivers.iter().map(|r| r.im.abs()).collect(),
                (None, Some(n)) => n.roots.roots.iter().map(|r| r.root.im.abs()).collect(),
                _ => Vec::new(),
            };
            leader_amplification(&a, &d, a.nrows() - 1, &frequencies)
        }
        _ => None,
    };
    let critical_scale_status = critical_status(&ring, &acyclic, &network);
    Ok(StabilityReport {
        scenario: sc.name().to_string(),
        certified: paper.certified,
        critical_scale_status,
        paper,
        ring,
        acyclic,
        chain_string_stability,
        leader_amplification,
        network: network.map(NetworkReport::Delayed),
        cacc: None,
        exactly_stable: verdict == ExactVerdict::Synchronizes,
        verdict,
        no_spanning_tree: None,
    })
}

/// The user's linear agents: delayed integrators `k_i e^{−sτ_i}/s` are the delayed drivers of
/// the graph `k_i a_ij` (pinning `k_i b_i`) and take their analysis; delay-free rational
/// agents take the closed-loop analysis of [`super::linear`].
fn analyse_linear_scenario(
    sc: &Scenario,
    m: &LinearModel,
    paper: TheoryReport,
    on_step: &(dyn Fn(&'static str) + Sync),
) -> Result<StabilityReport, AnalysisError> {
    let vehicles = m.graph.len() + usize::from(m.leader.is_some());
    if vehicles < 2 {
        return Err(AnalysisError::TooFewVehicles { vehicles });
    }
    let integrators = m.agents.iter().all(|a| a.transfer.is_integrator());
    if integrators && m.agents.iter().any(|a| a.transfer.delay_s > 0.0) {
        return analyse_delayed(sc, &as_delayed_drivers(m), paper, on_step);
    }
    let a = with_leader(&m.graph, m.leader.as_ref());
    if let Some(gap) = no_spanning_tree(&a) {
        return Ok(StabilityReport::unsynchronizable(sc, paper, gap));
    }
    on_step("closed-loop roots, their count by the argument principle, and the stable gain scales");
    let reference = paper
        .theorem1
        .as_ref()
        .map(|t| t.max_gain_scale)
        .or(paper.theorem1_plus.as_ref().map(|t| t.max_gain_scale))
        .filter(|c| c.is_finite());
    let r = super::linear::analyse_linear(m, reference).map_err(AnalysisError::Linear)?;
    let verdict = match (r.roots.certified, r.roots.abscissa < 0.0) {
        (false, _) => ExactVerdict::Uncertified,
        (true, true) => ExactVerdict::Synchronizes,
        (true, false) => ExactVerdict::DoesNotSynchronize,
    };
    let critical_scale_status = match r.critical.as_ref() {
        Some(c) if c.critical_gain_scale.is_some() && c.certified => CriticalScaleStatus::Certified,
        Some(c) if c.critical_gain_scale.is_some() => CriticalScaleStatus::Uncertified,
        _ => CriticalScaleStatus::None,
    };
    Ok(StabilityReport {
        scenario: sc.name().to_string(),
        certified: paper.certified,
        paper,
        ring: None,
        acyclic: None,
        chain_string_stability: None,
        leader_amplification: None,
        network: Some(NetworkReport::Linear(r)),
        cacc: None,
        exactly_stable: verdict == ExactVerdict::Synchronizes,
        critical_scale_status,
        verdict,
        no_spanning_tree: None,
    })
}

/// Linear agents that are all delayed integrators `k_i e^{−sτ_i}/s`, as the delayed drivers
/// of the graph with rows scaled by `k_i`.
fn as_delayed_drivers(m: &LinearModel) -> DelayedDriverModel {
    let k: Vec<f64> = m
        .agents
        .iter()
        .map(|a| a.transfer.eta[0] / a.transfer.rho[0])
        .collect();
    let arcs: Vec<crate::graph::Arc> = m
        .graph
        .arcs()
        .into_iter()
        .map(|arc| crate::graph::Arc {
            weight: arc.weight * k[arc.to],
            ..arc
        })
        .collect();
    // The shape's gains stand for every driver only when every k_i is the same.
    let shape = if k.iter().all(|&x| x == k[0]) {
        m.shape.scaled(k[0])
    } else {
        GraphShape::Other
    };
    DelayedDriverModel {
        graph: crate::graph::Graph::from_arcs(m.graph.len(), &arcs)
            .expect("scaling gains by positive k keeps a valid graph"),
        delay_s: m.agents.iter().map(|a| a.transfer.delay_s).collect(),
        delay_steps: m.delay_steps.clone(),
        leader: m
            .leader
            .as_ref()
            .map(|(v0, b)| (*v0, b.iter().zip(&k).map(|(b, k)| b * k).collect())),
        history: crate::delayed_driver::HistorySpec::default(),
        shape,
    }
}

/// The status of the critical scale the report prints: the search's certificate when the full
/// solve gave it, else the closed form.
fn critical_status(
    ring: &Option<RingModes>,
    acyclic: &Option<AcyclicReport>,
    network: &Option<NetworkStabilityReport>,
) -> CriticalScaleStatus {
    match network.as_ref().and_then(|n| n.critical.as_ref()) {
        Some(c) if c.certified => CriticalScaleStatus::Certified,
        Some(_) => CriticalScaleStatus::Uncertified,
        None if ring.is_some() || acyclic.is_some() => CriticalScaleStatus::ClosedForm,
        None => CriticalScaleStatus::None,
    }
}

fn cacc_params(c: &CaccModel) -> CaccParams {
    CaccParams {
        tau_s: c.tau_s.clone(),
        mu: c.mu.clone(),
        eta: c.eta.clone(),
        nu: c.nu[..c.nu.len().saturating_sub(1)].to_vec(),
    }
}

/// Platoon-scaling study of a CACC scenario: the paper's law with the scenario's mean gains
/// (homogeneous), the same with symmetric gap gains `η = ν = (η̄ + ν̄)/2`, and the
/// relative-velocity law of Barooah et al. with `k = (η̄ + ν̄)/2`, `b = μ̄`, symmetric and
/// with the velocity gains mistuned by ±50 %.
///
/// # Errors
/// [`AnalysisError::PlatoonScalingNeedsCacc`] for other models; a failed study.
pub fn platoon_scaling_study(
    sc: &Scenario,
    sizes: &[usize],
) -> Result<Vec<PlatoonScaling>, AnalysisError> {
    let Model::Cacc(c) = sc.model() else {
        return Err(AnalysisError::PlatoonScalingNeedsCacc);
    };
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let inner_nu = &c.nu[..c.nu.len().saturating_sub(1)];
    let (tau, mu, eta) = (mean(&c.tau_s), mean(&c.mu), mean(&c.eta));
    let nu = if inner_nu.is_empty() {
        eta
    } else {
        mean(inner_nu)
    };
    let k = 0.5 * (eta + nu);
    let laws = [
        PlatoonLaw::Cacc {
            tau_s: tau,
            mu,
            eta,
            nu,
        },
        PlatoonLaw::Cacc {
            tau_s: tau,
            mu,
            eta: k,
            nu: k,
        },
        PlatoonLaw::RelativeVelocity {
            k_front: k,
            k_back: k,
            b_front: mu,
            b_back: mu,
        },
        PlatoonLaw::RelativeVelocity {
            k_front: k,
            k_back: k,
            b_front: 1.5 * mu,
            b_back: 0.5 * mu,
        },
    ];
    laws.iter()
        .map(|&law| platoon_scaling(law, sizes).map_err(AnalysisError::PlatoonScaling))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::string_stability::chandler_string_peak;
    use super::*;
    use approx::assert_relative_eq;

    /// Chandler's road behind a leader, `n` drivers with gain `k` and delay `alpha`, read
    /// through the scenario format; `bidirectional` adds follower gains `k/2` (a graph with
    /// cycles, so the full solve and not the acyclic path).
    fn platoon(n: usize, k: f64, alpha: f64, bidirectional: bool) -> Scenario {
        let mut pinning = vec![0.0; n];
        pinning[0] = k;
        let graph = if bidirectional {
            let mut m = vec![vec![0.0; n]; n];
            for i in 0..n {
                if i > 0 {
                    m[i][i - 1] = k;
                }
                if i + 1 < n {
                    m[i][i + 1] = k / 2.0;
                }
            }
            serde_json::json!({"type": "matrix", "a": m})
        } else {
            serde_json::json!({"type": "chain", "gain": k})
        };
        let sc = serde_json::json!({
            "name": "platoon", "seed": 1, "step_s": 0.1, "horizon_s": 10, "vehicles": n,
            "road": {"type": "straight"},
            "model": {"type": "delayed_driver", "graph": graph, "delay_s": alpha,
                      "leader": {"speed_mps": 15.0, "pinning": pinning}}
        });
        Scenario::from_json(&sc.to_string()).unwrap()
    }

    #[test]
    fn stability_reports_the_worst_amplification_behind_a_leader() {
        // Chain: the last follower's peak is (sup_ω|H|)^N (closed form of |H|).
        let r = analyse(&platoon(10, 0.6, 1.0, false)).unwrap();
        let x = r.leader_amplification.unwrap();
        assert_relative_eq!(
            x.worst_peak,
            chandler_string_peak(0.6).powi(10),
            max_relative = 1e-8
        );
        assert_eq!(x.worst_vehicle, 9);
        // Bidirectional platoon (through the full solve): checked against a dense solve of
        // (iωI + e^{−iωα}L_f) T = e^{−iωα} b, at the reported frequency and on a fine grid.
        // (α = 1 would not synchronize: the backward gains k/2 raise d_i to 0.9.)
        let (n, k, alpha) = (10, 0.6, 0.6);
        let r = analyse(&platoon(n, k, alpha, true)).unwrap();
        assert!(r.network.is_some() && r.exactly_stable);
        let x = r.leader_amplification.unwrap();
        assert_eq!(x.peaks.len(), n);
        let gain = |w: f64| -> f64 {
            let s = num_complex::Complex64::new(0.0, w);
            let e = (-s * alpha).exp();
            let m = DMatrix::from_fn(n, n, |i, j| {
                // Diagonal: the predecessor (or the leader's pinning, for i = 0) and the follower.
                let lij = if i == j {
                    k + if i + 1 < n { k / 2.0 } else { 0.0 }
                } else if j + 1 == i {
                    -k
                } else if j == i + 1 {
                    -k / 2.0
                } else {
                    0.0
                };
                e * lij + if i == j { s } else { 0.0.into() }
            });
            let mut rhs = nalgebra::DVector::zeros(n);
            rhs[0] = e * k;
            let t = m.lu().solve(&rhs).unwrap();
            t.iter().map(|z| z.norm()).fold(0.0, f64::max)
        };
        assert_relative_eq!(
            gain(x.worst_frequency_rad_s),
            x.worst_peak,
            max_relative = 1e-9
        );
        for q in 1..=4000 {
            let w = 4.0 * 1.5 * k * q as f64 / 4000.0;
            assert!(gain(w) <= x.worst_peak * (1.0 + 1e-9), "ω = {w}");
        }
    }

    #[test]
    fn behind_a_leader_the_reference_is_theorem_one_plus_as_in_check() {
        // A bidirectional platoon (heterogeneous delays) and a leader graph with a cycle that
        // is not a chain: 0 ↔ 1 ↔ 2 → 3 → 0 with the leader pinning vehicles 0 and 2. The
        // reference of `stability` must be `check`'s Theorem 1+ scale, computed here by hand
        // from α_j (d_j^+ + 2 b_j) as well.
        let cyclic = serde_json::json!({
            "name": "cyclic", "seed": 1, "step_s": 0.1, "horizon_s": 10, "vehicles": 4,
            "road": {"type": "straight"},
            "model": {"type": "delayed_driver",
                      "graph": {"type": "edges", "edges": [
                          {"from": 1, "to": 0, "weight": 0.3}, {"from": 0, "to": 1, "weight": 0.5},
                          {"from": 2, "to": 1, "weight": 0.2}, {"from": 1, "to": 2, "weight": 0.4},
                          {"from": 2, "to": 3, "weight": 0.6}, {"from": 3, "to": 0, "weight": 0.1}]},
                      "delay_s": [0.4, 0.5, 0.6, 0.7],
                      "leader": {"speed_mps": 15.0, "pinning": [0.2, 0.0, 0.3, 0.0]}}
        });
        let cyclic = Scenario::from_json(&cyclic.to_string()).unwrap();
        let by_hand = |d: &[f64], alpha: &[f64], b: &[f64]| {
            let worst = (0..d.len())
                .map(|j| alpha[j] * (d[j] + 2.0 * b[j]))
                .fold(0.0, f64::max);
            0.5 / worst
        };
        let cases = [
            (
                platoon(8, 0.6, 0.6, true),
                by_hand(
                    &[0.3, 0.9, 0.9, 0.9, 0.9, 0.9, 0.9, 0.6],
                    &[0.6; 8],
                    &[0.6, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                ),
            ),
            (
                cyclic,
                by_hand(
                    &[0.4, 0.7, 0.4, 0.6],
                    &[0.4, 0.5, 0.6, 0.7],
                    &[0.2, 0.0, 0.3, 0.0],
                ),
            ),
        ];
        for (sc, expected) in cases {
            let r = analyse(&sc).unwrap();
            let check = r.paper.theorem1_plus.as_ref().unwrap().max_gain_scale;
            let c = r
                .network
                .as_ref()
                .and_then(|n| n.delayed())
                .unwrap()
                .critical
                .as_ref()
                .unwrap();
            assert_eq!(c.reference, super::super::ReferenceTheorem::Theorem1Plus);
            assert_relative_eq!(c.reference_gain_scale, check, max_relative = 1e-14);
            assert_relative_eq!(c.reference_gain_scale, expected, max_relative = 1e-14);
            assert_relative_eq!(
                c.conservatism_ratio,
                c.critical_gain_scale / check,
                max_relative = 1e-14
            );
            let json = serde_json::to_value(c).unwrap();
            assert_eq!(json["reference"], "theorem1_plus");
            assert!(r
                .network
                .as_ref()
                .and_then(|n| n.delayed())
                .unwrap()
                .to_string()
                .contains("Theorem 1+"));
        }
    }
}
