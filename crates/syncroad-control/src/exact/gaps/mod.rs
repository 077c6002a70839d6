//! Gap certificate of the delayed-driver law: will it make the cars touch?
//!
//! Eq. `chandler+` couples speeds, not gaps: a run can synchronize while the cars drive into
//! each other. The bumper gap of vehicle `i` to the vehicle ahead `p(i)` (`i − 1`; vehicle 0
//! follows `N − 1` on a ring and the leader on a straight road) obeys `g_i' = v_{p(i)} − v_i`,
//! so with the law linear in the speeds the gaps are linear in the initial speed perturbation:
//! `g(t) = g(0) + H(t) δv`, `H_ij(t)` the response of gap `i` to a unit initial speed change of
//! vehicle `j` (the pre-history of the scenario: speeds constant before 0, or no pending
//! reaction). Initial gap perturbations enter only through `g(0)`, since the law never reads a
//! gap. This module computes from the linear model:
//!
//! * the **final gaps** of the scenario's own initial state, exactly: with
//!   `M(s) = sI + diag(e^{−sα})L'` (`L'` the Laplacian, pinning gains on its diagonal) and the
//!   transformed pre-history `r(s) = δv + (I − diag(e^{−sα}))u₀/s` (`u₀ = −L'δv` for constant
//!   speeds, 0 without a pending reaction), `V(s) = M(s)⁻¹r(s) = v_∞/s·1 + z + O(s)` where
//!   `L'z + v_∞1 = δv + diag(α)u₀` (with `1ᵀz = 0` on a ring, `v_∞ = 0` behind a leader);
//!   then `g_i(∞) = g_i(0) + z_{p(i)} − z_i`;
//! * the **worst-case shrinkage** `M_i = sup_t Σ_j |H_ij(t)|` [m per m/s]: speed perturbations
//!   of at most `ε` per vehicle shrink gap `i` by at most `M_i ε`, and the sign pattern
//!   `δv_j = −ε sign H_{i*j}(t*)` reaches `M ε = max_i M_i ε`; so no contact for
//!   `ε < min_i g_i(0)/M_i`;
//! * the **scenario's own run** in the linear model: `min_t min_i g_i(t)`.
//!
//! Method: the trapezoidal rule for `v_i(t) = v_i(0) + ∫₀ᵗ u_i(τ − α_i) dτ` and the gaps on a
//! grid `h ≤ 0.01 s` that holds every delay (the scenario's delays are whole steps, so the
//! breakpoints `t = Σ kα_i` of the delay equation lie on the grid and the error expands in
//! `h²`), run at `h` and `2h` side by side: Richardson's extrapolation `(4g_h − g_{2h})/3` is
//! what is reported, `|g_h − g_{2h}|/3` the integration error. A uniform ring is circulant, so
//! one response serves every vehicle. The time sup runs until every response lies within
//! `1e-4` (relative) of its final value over a window of `max(10 s, 10 max α)`.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

mod cacc;

use super::analysis::uniform_ring;
use crate::scenario::Scenario;
use crate::scenario::{DelayedDriverModel, HistorySpec, Model};

/// How far a response may grow beyond the perturbation (relative to its size) before the
/// integration stops with [`GapError::Grows`].
pub const GROWTH_LIMIT: f64 = 1e6;

/// Largest network whose full response matrix `H(t)` is computed (its cost grows like `N²`).
pub const GAP_SOLVE_LIMIT: usize = 60;

/// Largest uniform ring (circulant: one response) certified.
pub const GAP_RING_LIMIT: usize = 400;

/// Longest time integrated [s]; a response still moving by then is reported as not settled.
pub const GAP_HORIZON_LIMIT_S: f64 = 3600.0;

/// Where a CACC platoon's safe perturbation binds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SafeBinding {
    /// The follower whose gap reaches contact.
    pub gap: usize,
    /// When [s].
    pub time_s: f64,
    /// The signs of the speed perturbations `δv_j = ε · pattern[j]` that do it.
    pub pattern: Vec<f64>,
}

/// Why no gap certificate was computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GapError {
    /// Too many vehicles for the response matrix.
    #[error("the gap certificate is computed for up to {limit} vehicles (uniform rings up to {ring_limit}); this scenario has {vehicles}")]
    TooLarge {
        /// Vehicles.
        vehicles: usize,
        /// [`GAP_SOLVE_LIMIT`].
        limit: usize,
        /// [`GAP_RING_LIMIT`].
        ring_limit: usize,
    },
    /// The responses grow past [`GROWTH_LIMIT`] times the perturbation: transient growth of a
    /// string-unstable network (which may still synchronize, slowly) or the growth of one that
    /// does not synchronize. The gaps' sup over the time integrated is a lower bound of `M`.
    #[error("transient growth: the linear responses exceed {growth:.0e} times the perturbation by t = {time_s:.1} s, and the gaps already move by M ≥ {shrinkage_at_least_m_per_mps:.4e} m per m/s, so no contact-free perturbation above {safe_at_most_mps:.4e} m/s can be certified; the network is string unstable or does not synchronize (`syncroad stability` says which)")]
    Grows {
        /// The growth that stopped the integration (relative to the perturbation).
        growth: f64,
        /// When the growth passed the limit [s].
        time_s: f64,
        /// The largest gap response so far, `sup_t max_i Σ_j |h_ij(t)|` up to `time_s`: a lower
        /// bound of `M` [m per m/s].
        shrinkage_at_least_m_per_mps: f64,
        /// The initial gap of the gap attaining it over that bound: no certificate can
        /// exceed this [m/s].
        safe_at_most_mps: f64,
    },
    /// The final-offset system is singular (no vehicle reaches all others).
    #[error(
        "the final gaps are not determined: no driver is reached by every other through the graph"
    )]
    Singular,
}

/// The gap certificate of a delayed-driver scenario (module documentation).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GapCertificate {
    /// Initial bumper gaps `g_i(0)` [m], the scenario's perturbation included.
    pub initial_gap_m: Vec<f64>,
    /// Where the gaps settle for the scenario's own initial state [m] (exact).
    pub final_gap_m: Vec<f64>,
    /// The speed every vehicle settles at [m/s].
    pub final_speed_mps: f64,
    /// `M_i = sup_t Σ_j |H_ij(t)|` per gap [m per m/s].
    pub shrinkage_m_per_mps: Vec<f64>,
    /// `M = max_i M_i` [m per m/s]: the largest shrinkage of any gap per m/s of speed
    /// perturbation (bounded per vehicle).
    pub worst_shrinkage_m_per_mps: f64,
    /// The gap attaining `M`.
    pub worst_gap: usize,
    /// When [s].
    pub worst_time_s: f64,
    /// The speed perturbation signs that attain it: `δv_j = ε · worst_pattern[j]`.
    pub worst_pattern: Vec<f64>,
    /// The largest speed perturbation that brings no contact [m/s]: `min_i g_i(0)/M_i` for
    /// the delayed-driver law, whose gaps only integrate speed differences; for a CACC
    /// platoon, whose law regulates gaps, `min_i min_t (d_i + E_i(t)) / Σ_j |h_ij(t)|` with
    /// `E_i` the spacing error the initial gap errors alone leave at `t` (a large initial gap
    /// closes while the perturbation acts).
    pub safe_perturbation_mps: f64,
    /// CACC platoons: where the safe perturbation binds — the gap, the time and the speed
    /// perturbation signs that bring that gap to contact there at `ε` just above it.
    #[serde(default)]
    pub safe_binding: Option<SafeBinding>,
    /// The scenario's own speed perturbation [m/s]: half the range of the initial speeds on
    /// a ring (a common offset does not move gaps), `max_j |v_j(0) − v_0|` behind a leader.
    pub own_perturbation_mps: f64,
    /// The smallest gap of the scenario's own run in the linear model [m].
    pub own_min_gap_m: f64,
    /// The vehicle whose gap that is.
    pub own_min_gap_vehicle: usize,
    /// When [s].
    pub own_min_gap_time_s: f64,
    /// `own_min_gap_m ≤ 0`: the scenario's own run makes contact.
    pub own_contact: bool,
    /// Time integrated [s].
    pub horizon_s: f64,
    /// Every response settled within tolerance before the horizon (else the sup is over
    /// `[0, horizon]` only).
    pub settled: bool,
    /// Integration step `h` [s] (the extrapolation also used `2h`).
    pub step_s: f64,
    /// Estimated integration error of the shrinkage [m per m/s] (0 for the exact
    /// exponential of a CACC platoon).
    pub integration_error_m_per_mps: f64,
    /// CACC platoons: `sup_t max_i |r_i(t)|`, the largest spacing error per m/s of a leader
    /// speed step (either sign) [m per m/s].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub leader_step_m_per_mps: Option<f64>,
    /// CACC platoons: the smallest gap of the scenario's own run with the law applied every
    /// step and held over it, as both backends apply it (the native run of the same law)
    /// [m]. The certificate's model is the continuous-time law, to which the sampled one
    /// converges at first order in the step; [`GapCertificate::own_contact`] counts both.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sampled_own_min_gap_m: Option<f64>,
}

/// The few numbers of a [`GapCertificate`] a run record and a sweep table keep.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct GapSummary {
    /// [`GapCertificate::worst_shrinkage_m_per_mps`].
    #[schemars(title = "worst gap shrinkage per m/s of speed perturbation")]
    pub worst_shrinkage_m_per_mps: f64,
    /// [`GapCertificate::safe_perturbation_mps`].
    #[schemars(title = "largest contact-free speed perturbation")]
    pub safe_perturbation_mps: f64,
    /// [`GapCertificate::own_perturbation_mps`].
    #[schemars(title = "the scenario's own speed perturbation")]
    pub own_perturbation_mps: f64,
    /// [`GapCertificate::own_min_gap_m`].
    #[schemars(title = "smallest gap of the scenario's own run (linear model)")]
    pub own_min_gap_m: f64,
    /// Smallest final gap of the scenario's own run [m].
    #[schemars(title = "smallest final gap")]
    pub final_min_gap_m: f64,
    /// [`GapCertificate::own_contact`].
    #[schemars(title = "contact predicted")]
    pub contact_predicted: bool,
    /// [`GapCertificate::settled`].
    #[schemars(title = "responses settled within the horizon")]
    pub settled: bool,
}

impl GapCertificate {
    /// The record's summary.
    pub fn summary(&self) -> GapSummary {
        GapSummary {
            worst_shrinkage_m_per_mps: self.worst_shrinkage_m_per_mps,
            safe_perturbation_mps: self.safe_perturbation_mps,
            own_perturbation_mps: self.own_perturbation_mps,
            own_min_gap_m: self.own_min_gap_m,
            final_min_gap_m: self
                .final_gap_m
                .iter()
                .cloned()
                .fold(f64::INFINITY, f64::min),
            contact_predicted: self.own_contact,
            settled: self.settled,
        }
    }
}

/// The linear delayed-driver network of a scenario, as the gap computation needs it.
pub(crate) struct LinearNetwork {
    /// `L'` (pinning on the diagonal), dense.
    pub(crate) laplacian: DMatrix<f64>,
    /// Delays α_i [s].
    pub(crate) delays_s: Vec<f64>,
    /// Delays in steps of the scenario.
    pub(crate) delay_steps: Vec<usize>,
    /// The vehicle ahead of each (None: the leader).
    pub(crate) ahead: Vec<Option<usize>>,
    /// A leader pins the network.
    pub(crate) leader: bool,
    /// Pre-history convention.
    pub(crate) history: HistorySpec,
}

impl LinearNetwork {
    pub(crate) fn of(sc: &Scenario, m: &DelayedDriverModel) -> Self {
        let n = sc.vehicles();
        let mut l = -m.graph.adjacency_dense();
        for i in 0..n {
            let row: f64 = (0..n).filter(|&j| j != i).map(|j| -l[(i, j)]).sum();
            l[(i, i)] = row + m.leader.as_ref().map_or(0.0, |(_, b)| b[i]);
        }
        let ahead = (0..n)
            .map(|i| match i {
                0 if sc.is_ring() => Some(n - 1),
                0 => None,
                _ => Some(i - 1),
            })
            .collect();
        LinearNetwork {
            laplacian: l,
            delays_s: m.delay_s.clone(),
            delay_steps: m.delay_steps.clone(),
            ahead,
            leader: m.leader.is_some(),
            history: m.history,
        }
    }

    /// `Δv_i = v_{p(i)} − v_i` of one column.
    fn gap_rate(&self, v: &[f64], i: usize) -> f64 {
        self.ahead[i].map_or(0.0, |p| v[p]) - v[i]
    }

    /// Final speed and gap offsets `z_{p(i)} − z_i` for an initial perturbation `dv`
    /// (module documentation).
    pub(crate) fn final_offsets(&self, dv: &[f64]) -> Result<(f64, Vec<f64>), GapError> {
        let n = dv.len();
        let l = &self.laplacian;
        let u0 = match self.history {
            HistorySpec::ConstantSpeeds => -(l * DVector::from_column_slice(dv)),
            HistorySpec::NoReaction => DVector::zeros(n),
        };
        let rhs: Vec<f64> = (0..n).map(|i| dv[i] + self.delays_s[i] * u0[i]).collect();
        let (v_inf, z) = if self.leader {
            let z = l
                .clone()
                .lu()
                .solve(&DVector::from_vec(rhs))
                .ok_or(GapError::Singular)?;
            (0.0, z)
        } else {
            let mut b = DMatrix::zeros(n + 1, n + 1);
            b.view_mut((0, 0), (n, n)).copy_from(l);
            for i in 0..n {
                b[(i, n)] = 1.0;
                b[(n, i)] = 1.0;
            }
            let mut r = DVector::zeros(n + 1);
            r.rows_mut(0, n).copy_from_slice(&rhs);
            let x = b.lu().solve(&r).ok_or(GapError::Singular)?;
            (x[n], x.rows(0, n).into_owned())
        };
        if !z.iter().all(|x| x.is_finite()) {
            return Err(GapError::Singular);
        }
        Ok((
            v_inf,
            (0..n).map(|i| self.gap_rate(z.as_slice(), i)).collect(),
        ))
    }
}

/// The trapezoidal rule for the linear network, `cols` experiments side by side, step `h`
/// with every delay `k_i` steps.
struct Integrator<'a> {
    net: &'a LinearNetwork,
    /// The nonzero entries `(i, j, L'_ij)`.
    entries: Vec<(usize, usize, f64)>,
    h: f64,
    k: Vec<usize>,
    cols: usize,
    v: Vec<f64>,
    gaps: Vec<f64>,
    /// Inputs `u^k`, row `k mod slots`.
    history: Vec<f64>,
    /// `u^0`, which is also `u^k` for `k < 0` with constant speeds before 0 (0 without a
    /// pending reaction).
    u_init: Vec<f64>,
    slots: usize,
    step: usize,
    /// Scratch.
    next: Vec<f64>,
    scratch: Vec<f64>,
    zeros: Vec<f64>,
}

impl<'a> Integrator<'a> {
    /// From initial speed perturbations `v0` (row-major `N × cols`), steps of `h` with
    /// `h_per_step` integration steps per scenario step.
    fn new(net: &'a LinearNetwork, v0: &[f64], cols: usize, h: f64, h_per_step: usize) -> Self {
        let n = net.delays_s.len();
        let k: Vec<usize> = net.delay_steps.iter().map(|m| m * h_per_step).collect();
        let slots = k.iter().copied().max().unwrap_or(0) + 2;
        let l = &net.laplacian;
        let entries = (0..n)
            .flat_map(|i| (0..n).map(move |j| (i, j)))
            .filter(|&(i, j)| l[(i, j)] != 0.0)
            .map(|(i, j)| (i, j, l[(i, j)]))
            .collect();
        let mut it = Integrator {
            net,
            entries,
            h,
            k,
            cols,
            v: v0.to_vec(),
            gaps: vec![0.0; n * cols],
            history: vec![0.0; slots * n * cols],
            u_init: Vec::new(),
            slots,
            step: 0,
            next: vec![0.0; n * cols],
            scratch: vec![0.0; n * cols],
            zeros: vec![0.0; n * cols],
        };
        let mut u0 = vec![0.0; n * cols];
        it.inputs(v0, &mut u0);
        it.history[..n * cols].copy_from_slice(&u0);
        it.u_init = u0;
        it
    }

    /// `u = −L'v` for every column.
    fn inputs(&self, v: &[f64], out: &mut [f64]) {
        inputs_into(&self.entries, self.cols, v, out);
    }

    /// The inputs `u^k` of every vehicle and column, seen as the right end of an interval when
    /// `right` (without a pending reaction `u` jumps at 0: its left limit is 0).
    fn row(&self, k: isize, right: bool) -> &[f64] {
        let nc = self.v.len();
        if k < 0 || (k == 0 && right && self.net.history == HistorySpec::NoReaction) {
            return match self.net.history {
                HistorySpec::ConstantSpeeds => &self.u_init,
                HistorySpec::NoReaction => &self.zeros,
            };
        }
        let r = (k as usize) % self.slots;
        &self.history[r * nc..(r + 1) * nc]
    }

    fn advance(&mut self) {
        let n = self.net.delays_s.len();
        let c = self.cols;
        let s = self.step as isize;
        let h = self.h;
        let mut next = std::mem::take(&mut self.next);
        for i in 0..n {
            let m = self.k[i] as isize;
            let a = &self.row(s - m, false)[i * c..(i + 1) * c];
            let v = &self.v[i * c..(i + 1) * c];
            let out = &mut next[i * c..(i + 1) * c];
            // Zipped slices of one length: no bounds checks, and the loops vectorize.
            if m >= 1 {
                let b = &self.row(s + 1 - m, true)[i * c..(i + 1) * c];
                for (((o, &v), &a), &b) in out.iter_mut().zip(v).zip(a).zip(b) {
                    *o = v + 0.5 * h * (a + b);
                }
            } else {
                // Undelayed drivers: Heun's predictor (the corrector follows below).
                for ((o, &v), &a) in out.iter_mut().zip(v).zip(a) {
                    *o = v + h * a;
                }
            }
        }
        if self.k.contains(&0) {
            let mut u = std::mem::take(&mut self.scratch);
            self.inputs(&next, &mut u);
            for i in (0..n).filter(|&i| self.k[i] == 0) {
                for p in 0..c {
                    let a = self.row(s, false)[i * c + p];
                    next[i * c + p] = self.v[i * c + p] + 0.5 * h * (a + u[i * c + p]);
                }
            }
            self.scratch = u;
        }
        for i in 0..n {
            let g = &mut self.gaps[i * c..(i + 1) * c];
            let (v, w) = (&self.v[i * c..(i + 1) * c], &next[i * c..(i + 1) * c]);
            match self.net.ahead[i] {
                Some(q) => {
                    let (vq, wq) = (&self.v[q * c..(q + 1) * c], &next[q * c..(q + 1) * c]);
                    for ((((g, &vq), &v), &wq), &w) in g.iter_mut().zip(vq).zip(v).zip(wq).zip(w) {
                        *g += 0.5 * h * ((vq - v) + (wq - w));
                    }
                }
                None => {
                    for ((g, &v), &w) in g.iter_mut().zip(v).zip(w) {
                        *g -= 0.5 * h * (v + w);
                    }
                }
            }
        }
        // The new inputs straight into their slot of the history.
        let nc = n * c;
        let r = ((s + 1) as usize) % self.slots;
        inputs_into(
            &self.entries,
            c,
            &next,
            &mut self.history[r * nc..(r + 1) * nc],
        );
        self.next = std::mem::replace(&mut self.v, next);
        self.step += 1;
    }
}

/// `u = −L'v` for every column of `v` (row-major `N × cols`), from the nonzero entries of `L'`.
fn inputs_into(entries: &[(usize, usize, f64)], c: usize, v: &[f64], out: &mut [f64]) {
    out.iter_mut().for_each(|x| *x = 0.0);
    for &(i, j, lij) in entries {
        let (o, x) = (&mut out[i * c..(i + 1) * c], &v[j * c..(j + 1) * c]);
        for (o, &x) in o.iter_mut().zip(x) {
            *o -= lij * x;
        }
    }
}

/// The gap certificate of a scenario: delayed drivers (module documentation) or a CACC
/// platoon ([`cacc`](self::cacc)); `Ok(None)` for models it does not cover.
///
/// # Errors
/// [`GapError`]: too many vehicles, growing responses, or final gaps not determined.
pub fn gap_certificate(sc: &Scenario) -> Result<Option<GapCertificate>, GapError> {
    let m = match sc.model() {
        Model::DelayedDriver(m) => m,
        Model::Cacc(c) => return cacc::cacc_gap_certificate(sc, c).map(Some),
        Model::Linear(_) => return Ok(None),
    };
    let n = sc.vehicles();
    if n == 0 {
        // An open road of inflows only: no fixed set whose gaps a certificate could bound.
        return Ok(None);
    }
    let circulant = uniform_ring(sc, m).is_some();
    if n > if circulant {
        GAP_RING_LIMIT
    } else {
        GAP_SOLVE_LIMIT
    } {
        return Err(GapError::TooLarge {
            vehicles: n,
            limit: GAP_SOLVE_LIMIT,
            ring_limit: GAP_RING_LIMIT,
        });
    }
    let net = LinearNetwork::of(sc, m);
    let v0 = sc.initial_speed_mps();
    // The speed the perturbation is measured from: the leader's, or the middle of the range.
    let reference = match &m.leader {
        Some((vl, _)) => *vl,
        None => {
            let lo = v0.iter().cloned().fold(f64::INFINITY, f64::min);
            let hi = v0.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
            0.5 * (lo + hi)
        }
    };
    let own: Vec<f64> = v0.iter().map(|v| v - reference).collect();
    let (final_speed, offsets) = net.final_offsets(&own)?;
    let g0 = sc.initial_gap_m().to_vec();
    let sweep = response_sup(&net, sc.step_s(), &own, &g0, circulant)?;
    let safe = (0..n)
        .map(|i| g0[i] / sweep.shrinkage[i])
        .fold(f64::INFINITY, f64::min);
    Ok(Some(GapCertificate {
        final_gap_m: (0..n).map(|i| g0[i] + offsets[i]).collect(),
        final_speed_mps: final_speed + reference,
        worst_shrinkage_m_per_mps: sweep.shrinkage[sweep.worst_gap],
        shrinkage_m_per_mps: sweep.shrinkage,
        worst_gap: sweep.worst_gap,
        worst_time_s: sweep.worst_time_s,
        worst_pattern: sweep.pattern,
        safe_perturbation_mps: safe,
        safe_binding: None,
        own_perturbation_mps: own.iter().map(|x| x.abs()).fold(0.0, f64::max),
        own_min_gap_m: sweep.own_min.0,
        own_min_gap_vehicle: sweep.own_min.1,
        own_min_gap_time_s: sweep.own_min.2,
        own_contact: sweep.own_min.0 <= 0.0,
        initial_gap_m: g0,
        horizon_s: sweep.horizon_s,
        settled: sweep.settled,
        step_s: sweep.h,
        integration_error_m_per_mps: sweep.error,
        leader_step_m_per_mps: None,
        sampled_own_min_gap_m: None,
    }))
}

/// What the time sweep of the responses found.
struct Sweep {
    shrinkage: Vec<f64>,
    worst_gap: usize,
    worst_time_s: f64,
    pattern: Vec<f64>,
    own_min: (f64, usize, f64),
    horizon_s: f64,
    settled: bool,
    h: f64,
    error: f64,
}

/// The experiments, row-major `N × (units + 1)`: unit perturbations of the first `units`
/// vehicles and the scenario's own `own`; with each column's final gap offsets and speed.
#[allow(clippy::type_complexity)]
fn columns(
    net: &LinearNetwork,
    own: &[f64],
    units: usize,
) -> Result<(Vec<f64>, Vec<f64>, Vec<f64>), GapError> {
    let n = own.len();
    let c = units + 1;
    let mut v0 = vec![0.0; n * c];
    for j in 0..units {
        v0[j * c + j] = 1.0;
    }
    for i in 0..n {
        v0[i * c + units] = own[i];
    }
    let mut finals = vec![0.0; n * c];
    let mut final_speed = vec![0.0; c];
    for p in 0..c {
        let col: Vec<f64> = (0..n).map(|i| v0[i * c + p]).collect();
        let (v_inf, off) = net.final_offsets(&col)?;
        final_speed[p] = v_inf;
        for i in 0..n {
            finals[i * c + p] = off[i];
        }
    }
    Ok((v0, finals, final_speed))
}

/// Runs the responses (unit perturbations of every vehicle, or of vehicle 0 on a circulant
/// ring, and the scenario's own `own`) at `h` and `2h` until they settle, and takes the sup.
fn response_sup(
    net: &LinearNetwork,
    scenario_step_s: f64,
    own: &[f64],
    g0: &[f64],
    circulant: bool,
) -> Result<Sweep, GapError> {
    let n = own.len();
    let units = if circulant { 1 } else { n };
    let c = units + 1;
    let (v0, finals, final_speed) = columns(net, own, units)?;
    let coarse_per_step = (scenario_step_s / 0.02).ceil().max(1.0) as usize;
    let h2 = scenario_step_s / coarse_per_step as f64;
    let mut coarse = Integrator::new(net, &v0, c, h2, coarse_per_step);
    let mut fine = Integrator::new(net, &v0, c, 0.5 * h2, 2 * coarse_per_step);
    let alpha_max = net.delays_s.iter().cloned().fold(0.0, f64::max);
    let mut settling = Settling {
        finals,
        final_speed,
        own_scale: own.iter().map(|x| x.abs()).fold(0.0, f64::max).max(1e-300),
        window_s: (10.0f64).max(10.0 * alpha_max),
        quiet_since: None,
    };
    let mut sup = Sup::new(n, units, circulant, g0);
    let mut tick = 0usize;
    let (settled, horizon_s) = loop {
        let t = tick as f64 * h2;
        sup.observe(t, &fine.gaps, &coarse.gaps);
        if tick.is_multiple_of(50) {
            if let Some(settled) = settling.check(t, &fine.v, &sup)? {
                break (settled, t);
            }
        }
        coarse.advance();
        fine.advance();
        fine.advance();
        tick += 1;
    };
    Ok(sup.into_sweep(horizon_s, settled, 0.5 * h2))
}

/// The sup over time of the extrapolated gap responses, and the scenario's own lowest gap,
/// kept as the integration runs ([`response_sup`]).
struct Sup<'a> {
    n: usize,
    units: usize,
    circulant: bool,
    g0: &'a [f64],
    /// Richardson's extrapolation `(4g_h − g_2h)/3` of every gap and column, row-major.
    e: Vec<f64>,
    /// Scratch of [`row_sums`].
    row_abs: Vec<f64>,
    row_err: Vec<f64>,
    shrinkage: Vec<f64>,
    /// The largest row sum so far: (sum, gap, time).
    best: (f64, usize, f64),
    pattern: Vec<f64>,
    /// The scenario's own lowest gap so far: (gap, vehicle, time).
    own_min: (f64, usize, f64),
    error: f64,
}

impl<'a> Sup<'a> {
    fn new(n: usize, units: usize, circulant: bool, g0: &'a [f64]) -> Self {
        Sup {
            n,
            units,
            circulant,
            g0,
            e: vec![0.0; n * (units + 1)],
            row_abs: vec![0.0; n],
            row_err: vec![0.0; n],
            shrinkage: vec![0.0; n],
            best: (0.0, 0, 0.0),
            pattern: vec![0.0; n],
            own_min: (f64::INFINITY, 0, 0.0),
            error: 0.0,
        }
    }

    /// Takes in the gaps of the fine (`h`) and coarse (`2h`) runs at time `t`.
    fn observe(&mut self, t: f64, fine: &[f64], coarse: &[f64]) {
        let (n, units) = (self.n, self.units);
        let c = units + 1;
        for ((x, &f), &g) in self.e.iter_mut().zip(fine).zip(coarse) {
            *x = (4.0 * f - g) / 3.0;
        }
        let e = &self.e;
        // A circulant ring: gap i's row is the column of vehicle 0, shifted.
        let ring_sum: f64 = if self.circulant {
            (0..n).map(|q| e[q * c].abs()).sum()
        } else {
            0.0
        };
        if self.circulant {
            let diff = |k: usize| (fine[k] - coarse[k]).abs() / 3.0;
            self.error = self.error.max((0..n).map(|q| diff(q * c)).sum());
        } else {
            row_sums(
                e,
                fine,
                coarse,
                c,
                units,
                &mut self.row_abs,
                &mut self.row_err,
            );
        }
        for i in 0..n {
            let row = &e[i * c..i * c + units];
            let sum: f64 = if self.circulant {
                ring_sum
            } else {
                self.error = self.error.max(self.row_err[i]);
                self.row_abs[i]
            };
            if sum > self.shrinkage[i] {
                self.shrinkage[i] = sum;
            }
            if sum > self.best.0 {
                self.best = (sum, i, t);
                for (j, x) in self.pattern.iter_mut().enumerate() {
                    let hij = if self.circulant {
                        e[((i + n - j) % n) * c]
                    } else {
                        row[j]
                    };
                    *x = -hij.signum() * f64::from(u8::from(hij != 0.0));
                }
            }
            let gap = self.g0[i] + e[i * c + units];
            if gap < self.own_min.0 {
                self.own_min = (gap, i, t);
            }
        }
    }

    fn into_sweep(self, horizon_s: f64, settled: bool, h: f64) -> Sweep {
        // Every gap of a circulant ring has the same response, shifted.
        let shrinkage = if self.circulant {
            vec![self.best.0; self.n]
        } else {
            self.shrinkage
        };
        Sweep {
            shrinkage,
            worst_gap: self.best.1,
            worst_time_s: self.best.2,
            pattern: self.pattern,
            own_min: self.own_min,
            horizon_s,
            settled,
            h,
            error: self.error,
        }
    }
}

/// When the responses have settled: every speed and extrapolated gap within `1e-4` (relative)
/// of its final value for a whole window, or the horizon limit reached.
struct Settling {
    /// Final gap offsets and speeds of every column ([`columns`]).
    finals: Vec<f64>,
    final_speed: Vec<f64>,
    /// The scenario's own perturbation, the scale of its column.
    own_scale: f64,
    window_s: f64,
    quiet_since: Option<f64>,
}

impl Settling {
    /// At time `t` with the fine run's speeds `v`: `Some(settled)` when the integration ends
    /// here, `None` to go on.
    ///
    /// # Errors
    /// [`GapError::Grows`] when a response grows beyond [`GROWTH_LIMIT`].
    fn check(&mut self, t: f64, v: &[f64], sup: &Sup) -> Result<Option<bool>, GapError> {
        let c = sup.units + 1;
        let scale = |k: usize| {
            if k % c == sup.units {
                self.own_scale
            } else {
                1.0
            }
        };
        let speed = (0..v.len())
            .map(|k| (v[k] - self.final_speed[k % c]).abs() / scale(k))
            .fold(0.0, f64::max);
        let best = sup.best;
        if !speed.is_finite() || speed > GROWTH_LIMIT {
            return Err(GapError::Grows {
                growth: GROWTH_LIMIT,
                time_s: t,
                shrinkage_at_least_m_per_mps: best.0,
                safe_at_most_mps: sup.g0[best.1] / best.0,
            });
        }
        let gaps = (0..sup.e.len())
            .map(|k| (sup.e[k] - self.finals[k]).abs() / scale(k))
            .fold(0.0, f64::max);
        let tol = 1e-4 * best.0.max(1e-3);
        if gaps <= tol && speed <= 1e-4 {
            let since = *self.quiet_since.get_or_insert(t);
            if t - since >= self.window_s {
                return Ok(Some(true));
            }
        } else {
            self.quiet_since = None;
        }
        Ok((t >= GAP_HORIZON_LIMIT_S).then_some(false))
    }
}

/// Rows of vehicles taken together by [`row_sums`].
const ROWS_AT_ONCE: usize = 4;

/// For every gap `i`: `Σ_j |e_ij|` into `abs` and the integration error `Σ_j |g_h − g_2h|/3`
/// into `err`, over the unit columns `j < units` of the row-major `N × c` tables (each sum
/// from the left, as a plain loop would add). Several rows are added at once: each sum is one
/// chain of dependent additions, and one row at a time left the processor waiting on it.
fn row_sums(
    e: &[f64],
    fine: &[f64],
    coarse: &[f64],
    c: usize,
    units: usize,
    abs: &mut [f64],
    err: &mut [f64],
) {
    let n = abs.len();
    let mut i0 = 0;
    while i0 < n {
        let rows = ROWS_AT_ONCE.min(n - i0);
        let (mut a, mut d) = ([0.0f64; ROWS_AT_ONCE], [0.0f64; ROWS_AT_ONCE]);
        for p in 0..units {
            for r in 0..rows {
                let k = (i0 + r) * c + p;
                a[r] += e[k].abs();
                d[r] += (fine[k] - coarse[k]).abs() / 3.0;
            }
        }
        abs[i0..i0 + rows].copy_from_slice(&a[..rows]);
        err[i0..i0 + rows].copy_from_slice(&d[..rows]);
        i0 += rows;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::native::{simulate, NativeOptions};
    use approx::assert_relative_eq;

    /// A ring of 8 drivers (bidirectional, gains 0.5/0.2, delays 0.3–0.6 s) or, with
    /// `leader`, a bidirectional platoon of 8 behind a leader at 15 m/s; `speeds` per vehicle,
    /// step 0.01 s (the native simulator's own error small beside the tolerances).
    fn scenario(leader: bool, speeds: &[f64], history: &str, horizon_s: f64) -> Scenario {
        let n = speeds.len();
        let delays: Vec<f64> = (0..n).map(|i| [0.3, 0.45, 0.6, 0.4][i % 4]).collect();
        let mut sc = serde_json::json!({
            "name": "gaps", "backend": "native", "seed": 3, "step_s": 0.01,
            "horizon_s": horizon_s, "vehicles": n,
            "road": {"type": "ring", "length_m": 25.0 * n as f64},
            "model": {"type": "delayed_driver",
                      "graph": {"type": "bidirectional_ring", "gain_pred": 0.5, "gain_follow": 0.2},
                      "delay_s": delays, "history": history},
            "initial": {"speed_mps": speeds, "perturbation": {"gap_m": 2.0}}
        });
        if leader {
            let mut a = vec![vec![0.0; n]; n];
            for i in 0..n {
                if i > 0 {
                    a[i][i - 1] = 0.5;
                }
                if i + 1 < n {
                    a[i][i + 1] = 0.2;
                }
            }
            let mut pin = vec![0.0; n];
            pin[0] = 0.5;
            sc["road"] = serde_json::json!({"type": "straight"});
            sc["initial"]["gap_m"] = serde_json::json!(20.0);
            sc["model"]["graph"] = serde_json::json!({"type": "matrix", "a": a});
            sc["model"]["leader"] = serde_json::json!({"speed_mps": 15.0, "pinning": pin});
        }
        Scenario::from_json(&sc.to_string()).unwrap()
    }

    /// The simulated gap of vehicle `i` at every sample.
    fn gap_series(sc: &Scenario, i: usize) -> Vec<(f64, f64)> {
        let run = simulate(sc, NativeOptions::default());
        let t = &run.trajectory;
        (0..t.len()).map(|k| (t.time_s[k], t.gaps(k)[i])).collect()
    }

    #[test]
    fn the_worst_sign_pattern_reaches_m_epsilon_and_random_perturbations_stay_within() {
        for leader in [false, true] {
            let base = if leader { 15.0 } else { 10.0 };
            let n = 8;
            let sc = scenario(leader, &vec![base; n], "constant_speeds", 200.0);
            let c = gap_certificate(&sc).unwrap().unwrap();
            assert!(c.settled && c.worst_shrinkage_m_per_mps > 0.0);
            let eps = 0.5;
            let speeds: Vec<f64> = c.worst_pattern.iter().map(|s| base + eps * s).collect();
            let worst = scenario(leader, &speeds, "constant_speeds", c.worst_time_s + 1.0);
            let i = c.worst_gap;
            let series = gap_series(&worst, i);
            let g0 = series[0].1;
            let at = series
                .iter()
                .min_by(|a, b| {
                    (a.0 - c.worst_time_s)
                        .abs()
                        .total_cmp(&(b.0 - c.worst_time_s).abs())
                })
                .unwrap();
            // The bound is reached (native step 0.01 s, sample within 0.005 s of t*).
            let shrink = g0 - at.1;
            assert_relative_eq!(
                shrink,
                c.worst_shrinkage_m_per_mps * eps,
                max_relative = 2e-3
            );
            // ... and is the sup over time for that pattern.
            let deepest = series
                .iter()
                .map(|s| g0 - s.1)
                .fold(f64::NEG_INFINITY, f64::max);
            assert!(deepest <= c.worst_shrinkage_m_per_mps * eps * (1.0 + 2e-3));
            // Random perturbations within ±ε never shrink any gap by more than M_i ε.
            let mut state = 0x1234_5678_9abc_def1u64;
            for _ in 0..6 {
                let speeds: Vec<f64> = (0..n)
                    .map(|_| {
                        state ^= state << 13;
                        state ^= state >> 7;
                        state ^= state << 17;
                        base + eps * (2.0 * ((state >> 11) as f64 / (1u64 << 53) as f64) - 1.0)
                    })
                    .collect();
                let sc = scenario(leader, &speeds, "constant_speeds", 150.0);
                let run = simulate(&sc, NativeOptions::default());
                let t = &run.trajectory;
                for i in 0..n {
                    let g0 = t.gaps(0)[i];
                    let low = (0..t.len())
                        .map(|k| t.gaps(k)[i])
                        .fold(f64::INFINITY, f64::min);
                    assert!(
                        g0 - low <= c.shrinkage_m_per_mps[i] * eps * (1.0 + 1e-3) + 1e-9,
                        "leader {leader}, gap {i}: {} > {}",
                        g0 - low,
                        c.shrinkage_m_per_mps[i] * eps
                    );
                }
            }
        }
    }

    #[test]
    fn predicted_final_gaps_equal_the_simulated_ones() {
        let speeds = [10.0, 11.2, 9.1, 10.4, 9.7, 10.9, 8.8, 10.2];
        for leader in [false, true] {
            for history in ["constant_speeds", "no_reaction"] {
                let v: Vec<f64> = speeds
                    .iter()
                    .map(|s| s + if leader { 5.0 } else { 0.0 })
                    .collect();
                let sc = scenario(leader, &v, history, 400.0);
                let c = gap_certificate(&sc).unwrap().unwrap();
                let run = simulate(&sc, NativeOptions::default());
                let t = &run.trajectory;
                let last = t.len() - 1;
                for i in 0..8 {
                    assert!(
                        (t.gaps(last)[i] - c.final_gap_m[i]).abs() < 2e-3,
                        "leader {leader}, {history}, gap {i}: simulated {} predicted {}",
                        t.gaps(last)[i],
                        c.final_gap_m[i]
                    );
                    assert!((t.speeds(last)[i] - c.final_speed_mps).abs() < 1e-4);
                }
                // The scenario's own minimum gap, by the linear model, as simulated.
                let low = (0..t.len())
                    .flat_map(|k| t.gaps(k).to_vec())
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    (low - c.own_min_gap_m).abs() < 2e-3,
                    "{low} vs {}",
                    c.own_min_gap_m
                );
            }
        }
    }

    #[test]
    fn the_weak_gain_demo_ring_is_predicted_to_make_contact_before_it_runs() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../scenarios/sugiyama-ring.json"
        );
        let ring = Scenario::load(std::path::Path::new(path)).unwrap();
        let weak = ring.scaled(0.25, 1.0).unwrap().scenario;
        let c = gap_certificate(&weak).unwrap().unwrap();
        assert!(c.own_contact && c.own_min_gap_m < 0.0, "{c:?}");
        assert!(c.safe_perturbation_mps < c.own_perturbation_mps);
        // The native simulator (the scenario's own step, 0.1 s) agrees on the depth.
        let run = simulate(&weak, NativeOptions::default());
        let t = &run.trajectory;
        let low = (0..t.len())
            .flat_map(|k| t.gaps(k).to_vec())
            .fold(f64::INFINITY, f64::min);
        assert!(
            low < 0.0 && (low - c.own_min_gap_m).abs() < 0.05,
            "{low} vs {}",
            c.own_min_gap_m
        );
        // At the original gains there is no contact.
        let c = gap_certificate(&ring).unwrap().unwrap();
        assert!(!c.own_contact && c.own_min_gap_m > 0.0);
    }

    #[test]
    fn a_uniform_ring_uses_one_response_and_agrees_with_the_full_matrix() {
        // Circulant ring (uniform gains and delays) against the same ring given as a matrix
        // (not recognised as uniform: all N responses): the same M and the same own run.
        let mk = |graph: serde_json::Value| {
            Scenario::from_json(
                &serde_json::json!({
                    "name": "u", "backend": "native", "seed": 1, "step_s": 0.1, "horizon_s": 10,
                    "vehicles": 10, "road": {"type": "ring", "length_m": 250},
                    "model": {"type": "delayed_driver", "graph": graph, "delay_s": 0.5},
                    "initial": {"speed_mps": 10, "perturbation": {"speed_mps": 1.0}}
                })
                .to_string(),
            )
            .unwrap()
        };
        let a: Vec<Vec<f64>> = (0..10)
            .map(|i| {
                (0..10)
                    .map(|j| if j == (i + 9) % 10 { 0.6 } else { 0.0 })
                    .collect()
            })
            .collect();
        let uniform = gap_certificate(&mk(
            serde_json::json!({"type": "unidirectional_ring", "gain": 0.6}),
        ))
        .unwrap()
        .unwrap();
        let full = gap_certificate(&mk(serde_json::json!({"type": "matrix", "a": a})))
            .unwrap()
            .unwrap();
        assert_relative_eq!(
            uniform.worst_shrinkage_m_per_mps,
            full.worst_shrinkage_m_per_mps,
            max_relative = 1e-9
        );
        for i in 0..10 {
            assert_relative_eq!(
                uniform.shrinkage_m_per_mps[i],
                full.shrinkage_m_per_mps[i],
                max_relative = 1e-9
            );
        }
        assert_relative_eq!(
            uniform.own_min_gap_m,
            full.own_min_gap_m,
            max_relative = 1e-9
        );
    }

    #[test]
    fn errors_name_the_limit() {
        let sc = Scenario::from_json(
            &serde_json::json!({
                "name": "big", "backend": "native", "seed": 1, "step_s": 0.1, "horizon_s": 10,
                "vehicles": 61, "road": {"type": "ring", "length_m": 2000},
                "model": {"type": "delayed_driver",
                          "graph": {"type": "unidirectional_ring", "gain": 0.6},
                          "delay_s": (0..61).map(|i| 0.3 + 0.1 * (i % 3) as f64).collect::<Vec<_>>()},
                "initial": {"speed_mps": 10}
            })
            .to_string(),
        )
        .unwrap();
        assert_eq!(
            gap_certificate(&sc).unwrap_err().to_string(),
            "the gap certificate is computed for up to 60 vehicles (uniform rings up to 400); this scenario has 61"
        );
    }
}
