//! The delayed-driver law, eq. `chandler+`:
//! `v_i'(t) = u_i(t − α_i)`, `u_i(t) = Σ_j a_ij (v_j(t) − v_i(t)) + b_i (v_0 − v_i(t))`.
//!
//! The law owns one delay buffer per driver and nothing else: each call to
//! [`DelayedDriverLaw::step`] takes the measured speeds `v^n` and returns the speeds `v^{n+1}`
//! the drivers produce over the next step. The native simulator applies them exactly; the SUMO
//! loop commands them.
//!
//! # Discretisation
//! With α_i = m_i Δt on the step grid, `v_i^{n+1} = v_i^n + ∫_{t_n}^{t_{n+1}} u_i(s − α_i) ds` and
//! every input the integral needs is already known when m_i ≥ 1, so the scheme is explicit:
//! * m_i ≥ 2: the cubic through `u^{n−m−1} … u^{n+2−m}`, weights (−1, 13, 13, −1)/24 (fourth order);
//! * m_i = 1: the quadratic through `u^{n−2}, u^{n−1}, u^n`, weights (−1, 8, 5)/12 (third order);
//! * m_i = 0: Heun's predictor–corrector (second order).
//!
//! The breakpoints t = kα_i of a delay equation (kinks of the solution, all on the grid) keep
//! the global error at second order, as the convergence test in `tests/paper.rs` shows; the
//! higher-order stencils cut its constant about tenfold against the trapezoidal rule.

use serde::{Deserialize, Serialize};

use crate::graph::Graph;
use crate::sensed::{Neighbors, Sensed};

/// Delay-buffer history before t = 0 (`model.history` in scenario files).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HistorySpec {
    /// Speeds were constant at their initial values for t ≤ 0 (the usual DDE initial function):
    /// drivers react to the initial speed differences from t = 0 on.
    #[default]
    ConstantSpeeds,
    /// No reaction was pending: `u_i(t) = 0` for t < 0, so driver i first reacts at t = α_i.
    NoReaction,
}

/// Errors raised when building a [`DelayedDriverLaw`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LawError {
    /// A per-vehicle slice has the wrong length.
    #[error("{what} has {len} entries but the graph has {n} vehicles")]
    LengthMismatch {
        /// Which input.
        what: &'static str,
        /// Its length.
        len: usize,
        /// Number of vehicles.
        n: usize,
    },
    /// The step is not a positive finite number.
    #[error("step Δt = {0} s must be a finite number > 0")]
    BadStep(f64),
}

/// The delayed-driver law with per-driver delay buffers.
#[derive(Debug, Clone)]
pub struct DelayedDriverLaw {
    n: usize,
    dt_s: f64,
    row_start: Vec<usize>,
    cols: Vec<usize>,
    weights: Vec<f64>,
    /// Pinning gains b_i (empty when there is no leader).
    pinning: Vec<f64>,
    /// Delays m_i in steps.
    delay_steps: Vec<usize>,
    any_undelayed: bool,
    /// Ring buffer of past inputs, `slots` rows of `n`: row `k mod slots` holds `u^k`.
    history: Vec<f64>,
    slots: usize,
    /// Row of the current step n.
    head: usize,
    /// Scratch for Heun's predictor.
    predicted: Vec<f64>,
    /// Steps taken so far (the index n of the next step).
    steps_done: usize,
    /// Pre-history `u = 0` (no pending reaction): stencils must not reach across t = 0.
    no_reaction: bool,
    /// Where each edge points this step when the graph is taken from the simulator
    /// ([`DelayedDriverLaw::sense`]); `None`: the fixed graph.
    sensed: Option<Vec<Source>>,
}

/// What the speed `v_j` of one edge `a_ij (v_j − v_i)` is, when the graph is sensed.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Source {
    /// The measured speed of the edge's own vehicle `j`.
    Measured,
    /// The speed of another vehicle in `j`'s place.
    Other(f64),
    /// Nobody there: the term drops.
    Dropped,
}

impl DelayedDriverLaw {
    /// A law for `graph` with delays `delay_steps` (α_i = m_i Δt), step `dt_s`, optional
    /// pinning gains `b_i` toward a leader, and the initial speeds that seed the history.
    pub fn new(
        graph: &Graph,
        delay_steps: &[usize],
        dt_s: f64,
        pinning: Option<&[f64]>,
        initial_speeds_mps: &[f64],
        leader_speed_mps: Option<f64>,
        history: HistorySpec,
    ) -> Result<Self, LawError> {
        let n = graph.len();
        if delay_steps.len() != n {
            return Err(LawError::LengthMismatch {
                what: "delay_steps",
                len: delay_steps.len(),
                n,
            });
        }
        if initial_speeds_mps.len() != n {
            return Err(LawError::LengthMismatch {
                what: "initial_speeds_mps",
                len: initial_speeds_mps.len(),
                n,
            });
        }
        if let Some(b) = pinning {
            if b.len() != n {
                return Err(LawError::LengthMismatch {
                    what: "pinning",
                    len: b.len(),
                    n,
                });
            }
        }
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return Err(LawError::BadStep(dt_s));
        }
        let (rs, cols, w) = graph.csr();
        // Rows u^{n−m−1} … u^n must be kept: m_max + 2 rows.
        let slots = delay_steps.iter().copied().max().unwrap_or(0) + 2;
        let mut law = Self {
            n,
            dt_s,
            row_start: rs.to_vec(),
            cols: cols.to_vec(),
            weights: w.to_vec(),
            pinning: pinning.map(<[f64]>::to_vec).unwrap_or_default(),
            delay_steps: delay_steps.to_vec(),
            any_undelayed: delay_steps.contains(&0),
            history: vec![0.0; slots * n],
            slots,
            head: 0,
            predicted: vec![0.0; n],
            steps_done: 0,
            no_reaction: history == HistorySpec::NoReaction,
            sensed: None,
        };
        if history == HistorySpec::ConstantSpeeds {
            let mut u0 = vec![0.0; n];
            law.inputs(initial_speeds_mps, leader_speed_mps.unwrap_or(0.0), &mut u0);
            for s in 0..slots {
                law.history[s * n..(s + 1) * n].copy_from_slice(&u0);
            }
        }
        // The first call to `step` writes u^0 into row 0 and reads rows -m_i (prefilled).
        law.head = slots - 1;
        Ok(law)
    }

    /// Number of drivers.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Always false: a law has at least one driver.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Step Δt [s].
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// Takes the graph from the simulator for the next [`DelayedDriverLaw::step`]: driver i
    /// is vehicle `i + offset` of `neighbors` (offset 1 behind a leader vehicle), and each
    /// edge to its layout predecessor or follower points at whoever is there now
    /// ([`crate::sensed`]). The inputs computed at this step keep what the drivers saw: each
    /// acts on its own after its delay, whoever is ahead by then.
    pub fn sense(&mut self, neighbors: &Neighbors, offset: usize) {
        let mut src = self.sensed.take().unwrap_or_default();
        src.clear();
        for i in 0..self.n {
            for k in self.row_start[i]..self.row_start[i + 1] {
                src.push(match neighbors.edge(i + offset, self.cols[k] + offset) {
                    Sensed::Layout => Source::Measured,
                    Sensed::Other { speed_mps, .. } => Source::Other(speed_mps),
                    Sensed::Nobody => Source::Dropped,
                });
            }
        }
        self.sensed = Some(src);
    }

    /// Computes the inputs `u_i = Σ_j a_ij (v_j − v_i) + b_i (v_0 − v_i)` (eq. `proto-lin+`).
    #[inline]
    fn inputs(&self, v: &[f64], v0: f64, u: &mut [f64]) {
        let rs = &self.row_start;
        match &self.sensed {
            None => {
                for i in 0..self.n {
                    let vi = v[i];
                    let mut acc = 0.0;
                    for k in rs[i]..rs[i + 1] {
                        acc += self.weights[k] * (v[self.cols[k]] - vi);
                    }
                    u[i] = acc;
                }
            }
            Some(src) => {
                for i in 0..self.n {
                    let vi = v[i];
                    let mut acc = 0.0;
                    for k in rs[i]..rs[i + 1] {
                        let vj = match src[k] {
                            Source::Measured => v[self.cols[k]],
                            Source::Other(s) => s,
                            Source::Dropped => continue,
                        };
                        acc += self.weights[k] * (vj - vi);
                    }
                    u[i] = acc;
                }
            }
        }
        if !self.pinning.is_empty() {
            for i in 0..self.n {
                u[i] += self.pinning[i] * (v0 - v[i]);
            }
        }
    }

    /// The input `u_i^n` computed at the last step (what driver i will act on m_i steps later).
    pub fn latest_inputs(&self) -> &[f64] {
        &self.history[self.head * self.n..(self.head + 1) * self.n]
    }

    /// One step: from the measured speeds `v^n` (and leader speed `v_0`, ignored without
    /// pinning) computes the speeds `v^{n+1}` into `next`.
    ///
    /// # Panics
    /// If the slices do not have one entry per driver.
    pub fn step(&mut self, speeds_mps: &[f64], leader_speed_mps: f64, next_mps: &mut [f64]) {
        let n = self.n;
        assert_eq!(speeds_mps.len(), n, "one speed per driver");
        assert_eq!(next_mps.len(), n, "one output per driver");
        self.head = if self.head + 1 == self.slots {
            0
        } else {
            self.head + 1
        };
        let head = self.head;
        // u^n into the head row.
        let mut row = std::mem::take(&mut self.history);
        self.inputs(
            speeds_mps,
            leader_speed_mps,
            &mut row[head * n..(head + 1) * n],
        );
        self.history = row;
        let h = self.dt_s;
        let slots = self.slots;
        let hist = &self.history;
        // Row index of u^{n−k} for k ≤ slots − 1.
        let back = |k: usize| {
            if head >= k {
                head - k
            } else {
                head + slots - k
            }
        };
        let step_n = self.steps_done;
        self.steps_done += 1;
        // With a jump at t = 0 (no-reaction history) the stencils may not straddle it: the
        // first steps of each driver use one-sided rules (see `startup_increment`).
        let startup = self.no_reaction && step_n <= slots;
        for i in 0..n {
            let m = self.delay_steps[i];
            if startup && step_n < m + 2 {
                next_mps[i] =
                    speeds_mps[i] + h * startup_increment(step_n, m, |k| hist[back(k) * n + i]);
            } else if m >= 2 {
                // Rows of u^{n−m−1}, u^{n−m}, u^{n+1−m}, u^{n+2−m}.
                let r0 = back(m + 1);
                let r1 = if r0 + 1 == slots { 0 } else { r0 + 1 };
                let r2 = if r1 + 1 == slots { 0 } else { r1 + 1 };
                let r3 = if r2 + 1 == slots { 0 } else { r2 + 1 };
                let (a, b, c, d) = (
                    hist[r0 * n + i],
                    hist[r1 * n + i],
                    hist[r2 * n + i],
                    hist[r3 * n + i],
                );
                next_mps[i] = speeds_mps[i] + h * (13.0 * (b + c) - (a + d)) * (1.0 / 24.0);
            } else if m == 1 {
                let (a, b, c) = (
                    hist[back(2) * n + i],
                    hist[back(1) * n + i],
                    hist[head * n + i],
                );
                next_mps[i] = speeds_mps[i] + h * (8.0 * b + 5.0 * c - a) * (1.0 / 12.0);
            }
        }
        if self.any_undelayed {
            self.heun_for_undelayed(speeds_mps, leader_speed_mps, next_mps);
        }
    }

    /// Heun's step for drivers with m_i = 0: predict every speed with Euler on its own
    /// delayed input, then average u^n and the predicted u^{n+1}.
    #[cold]
    fn heun_for_undelayed(&mut self, v: &[f64], v0: f64, next: &mut [f64]) {
        let n = self.n;
        let head = self.head;
        let mut pred = std::mem::take(&mut self.predicted);
        for i in 0..n {
            let m = self.delay_steps[i];
            let a = if head >= m {
                head - m
            } else {
                head + self.slots - m
            };
            pred[i] = v[i] + self.dt_s * self.history[a * n + i];
        }
        let mut u_pred = vec![0.0; n];
        self.inputs(&pred, v0, &mut u_pred);
        for i in 0..n {
            if self.delay_steps[i] == 0 {
                next[i] = v[i] + 0.5 * self.dt_s * (self.history[head * n + i] + u_pred[i]);
            }
        }
        self.predicted = pred;
    }
}

/// Mean of the delayed input over step `n` for a driver with delay `m ≥ 1` when the input
/// history is zero before t = 0 and `u^0` may jump: only nodes `u^k`, `k ≥ 0`, are used.
/// `u(k)` returns `u^{n−k}`.
fn startup_increment(n: usize, m: usize, u: impl Fn(usize) -> f64) -> f64 {
    if m == 0 {
        return 0.0; // handled by Heun's step
    }
    if n < m {
        return 0.0; // the whole interval lies before t = 0
    }
    if n > m {
        // The left node is u^1 or later: the interior stencils only reach back to u^0.
        return if m >= 2 {
            (13.0 * (u(m) + u(m - 1)) - (u(m + 1) + u(m - 2))) / 24.0
        } else {
            (8.0 * u(1) + 5.0 * u(0) - u(2)) / 12.0
        };
    }
    // The interval is [0, 1] in steps: one-sided rules from u^0.
    if m >= 2 {
        // Quadratic through u^0, u^1, u^2: (5, 8, −1)/12.
        (5.0 * u(m) + 8.0 * u(m - 1) - u(m - 2)) / 12.0
    } else {
        0.5 * (u(1) + u(0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn ring_law(
        n: usize,
        k: f64,
        m: usize,
        dt: f64,
        v: &[f64],
        h: HistorySpec,
    ) -> DelayedDriverLaw {
        let g = Graph::unidirectional_ring(n, &vec![k; n]).unwrap();
        DelayedDriverLaw::new(&g, &vec![m; n], dt, None, v, None, h).unwrap()
    }

    /// The graph from the simulator: with everyone where the layout put them the law is the
    /// fixed graph's law bit for bit; with another vehicle ahead of driver 2 and nobody behind
    /// driver 0, the inputs are the paper's sum over the edges as they point now, by hand.
    #[test]
    fn a_sensed_graph_retargets_the_edges_to_the_neighbours_only() {
        // Driver `to` observes vehicle `from` with gain `weight`.
        let arc = |to, from, weight| crate::graph::Arc { from, to, weight };
        let g = Graph::from_arcs(
            4,
            &[
                arc(1, 0, 0.6),
                arc(2, 1, 0.6),
                arc(3, 2, 0.6),
                arc(0, 3, 0.6),
                arc(0, 1, 0.1),
                arc(1, 2, 0.1),
                arc(2, 0, 0.25),
            ],
        )
        .unwrap();
        let v0 = [8.0, 9.0, 7.5, 10.0];
        let mk = || {
            DelayedDriverLaw::new(
                &g,
                &[2; 4],
                0.1,
                None,
                &v0,
                None,
                HistorySpec::ConstantSpeeds,
            )
            .unwrap()
        };
        let (mut fixed, mut sensed) = (mk(), mk());
        let layout = Neighbors::layout(4, true);
        let (mut v, mut a, mut b) = (v0.to_vec(), vec![0.0; 4], vec![0.0; 4]);
        for _ in 0..50 {
            fixed.step(&v, 0.0, &mut a);
            sensed.sense(&layout, 0);
            sensed.step(&v, 0.0, &mut b);
            assert_eq!(a, b);
            v.copy_from_slice(&a);
        }
        let mut nb = layout.clone();
        nb.ahead[2] = Sensed::Other {
            speed_mps: 3.0,
            gap_m: 12.0,
        };
        nb.behind[0] = Sensed::Nobody;
        sensed.sense(&nb, 0);
        sensed.step(&v, 0.0, &mut b);
        let u = sensed.latest_inputs();
        // Driver 0: 0.6 (v3 − v0), its look behind at vehicle 1 dropped.
        assert_eq!(u[0], 0.6 * (v[3] - v[0]));
        assert_eq!(u[1], 0.6 * (v[0] - v[1]) + 0.1 * (v[2] - v[1]));
        // Driver 2: 0.6 toward the other vehicle's 3 m/s, and the radio link to vehicle 0 stays.
        assert_relative_eq!(
            u[2],
            0.6 * (3.0 - v[2]) + 0.25 * (v[0] - v[2]),
            epsilon = 1e-15
        );
        assert_eq!(u[3], 0.6 * (v[2] - v[3]));
    }

    #[test]
    fn equal_speeds_stay_equal() {
        let v = vec![7.0; 5];
        let mut law = ring_law(5, 0.4, 3, 0.1, &v, HistorySpec::ConstantSpeeds);
        let mut next = vec![0.0; 5];
        law.step(&v, 0.0, &mut next);
        assert_eq!(next, v);
    }

    #[test]
    fn no_reaction_history_delays_the_first_response_by_exactly_m_steps() {
        // Vehicle 1 sees vehicle 0 going 1 m/s faster; with m = 3 it must not move during
        // the first 3 steps, then accelerate.
        let mut v = vec![11.0, 10.0];
        let g = Graph::chain(2, &[0.0, 0.5]).unwrap();
        let mut law =
            DelayedDriverLaw::new(&g, &[3, 3], 0.1, None, &v, None, HistorySpec::NoReaction)
                .unwrap();
        let mut next = vec![0.0; 2];
        for step in 0..6 {
            law.step(&v, 0.0, &mut next);
            if step < 2 {
                assert_eq!(next[1], 10.0, "step {step}");
            }
            v.copy_from_slice(&next);
        }
        // Step 2 uses (u^{-1} + u^0)/2 = 0.25, later steps the full 0.5 (minus the tiny change).
        assert!(v[1] > 10.0 + 0.1 * 0.25 + 0.1 * 0.45, "{}", v[1]);
        assert_eq!(v[0], 11.0);
    }

    #[test]
    fn pinned_driver_without_delay_tracks_leader_exponentially() {
        // v' = b (v0 − v), no delay: v(t) = v0 + (v(0) − v0) e^{−bt}. Heun's error is O(Δt²).
        let g = Graph::from_arcs(1, &[]).unwrap();
        let dt = 0.01;
        let mut law = DelayedDriverLaw::new(
            &g,
            &[0],
            dt,
            Some(&[0.5]),
            &[5.0],
            Some(10.0),
            HistorySpec::ConstantSpeeds,
        )
        .unwrap();
        let mut v = vec![5.0];
        let mut next = vec![0.0];
        for _ in 0..400 {
            law.step(&v, 10.0, &mut next);
            v.copy_from_slice(&next);
        }
        let exact = 10.0 - 5.0 * (-0.5f64 * 4.0).exp();
        assert_relative_eq!(v[0], exact, epsilon = 1e-5);
    }

    #[test]
    fn length_mismatch_is_reported() {
        let g = Graph::unidirectional_ring(3, &[1.0; 3]).unwrap();
        let e = DelayedDriverLaw::new(
            &g,
            &[1, 1],
            0.1,
            None,
            &[0.0; 3],
            None,
            HistorySpec::NoReaction,
        )
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "delay_steps has 2 entries but the graph has 3 vehicles"
        );
    }
}
