//! Exact stability of a network of the user's rational agents (no delays): the roots of
//!
//! `P_c(s) = det(diag(s ρ_i(s)) + c · diag(η_i(s)) · H)`, `H = L + diag(b)`,
//!
//! other than the consensus root `s = 0` (absent behind a leader), the verdict, and how it
//! changes with the gain scale `c` (every `a_ij` and `b_i` multiplied by `c`).
//!
//! * **Roots**: the eigenvalues of the closed loop `A − c B H (I + c D H)^{−1} C` of the agents'
//!   canonical realisations ([`crate::agents::linear`]), whose characteristic polynomial is
//!   `P_c` up to a constant; the consensus root is the one at zero.
//! * **Certificate**: the number of roots right of the axis is counted a second way, by the
//!   argument principle on `P_c(iω)/(iω)` along the imaginary axis (the phase of a determinant
//!   evaluated by LU, tracked on a logarithmic grid refined around every root near the axis,
//!   with steps bisected until each turns less than π/4); the verdict is certified when the
//!   two agree and no root lies within round-off of the axis.
//! * **Stable scales**: the spectral abscissa on a logarithmic grid of `c` from `10⁻⁶` to `10⁶`
//!   (one point per decade: a window of stable or unstable scales narrower than a decade
//!   between two grid points is missed), each change of sign refined by bisection and then
//!   Illinois regula falsi to `1e-13` relative. The
//!   set of stable scales is reported as intervals: an agent whose ρ is not Hurwitz makes the
//!   network unstable for small `c` and can synchronize above a threshold. `c*` is the top of
//!   the first stable interval; each crossing is checked by generalized Nyquist, `−1/c*` an
//!   eigenvalue of `H · diag(W_i(iω*))`, measured as the smallest singular value of
//!   `I/c* + H diag(W(iω*))` relative to its largest. Above `10⁶` the search stops: a network
//!   stable there is reported with no critical scale, as searched and not proven.

use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use serde::Serialize;

use crate::agents::Transfer;
use crate::model::LinearModel;

/// A root `s = re + i·im` \[1/s\].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LinearRoot {
    /// Real part.
    pub re: f64,
    /// Imaginary part.
    pub im: f64,
}

/// The roots at the scenario's gains (`c = 1`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LinearRoots {
    /// Order of the closed loop (Σ of the agents' orders).
    pub dimension: usize,
    /// Largest real part of a root other than consensus \[1/s\].
    pub abscissa: f64,
    /// The rightmost roots (up to 12, conjugates both listed).
    pub roots: Vec<LinearRoot>,
    /// Roots right of the imaginary axis by the eigenvalues.
    pub unstable_roots: usize,
    /// Roots right of the imaginary axis by the argument principle (`None` when the count
    /// failed to close).
    pub counted_unstable_roots: Option<usize>,
    /// The two counts agree and no root lies on the axis within round-off.
    pub certified: bool,
}

/// How the verdict changes with the gain scale.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LinearCritical {
    /// `c*`: the top of the first interval of stable scales (`None`: stable up to the
    /// search's end, or never stable).
    pub critical_gain_scale: Option<f64>,
    /// `ω*` [rad/s]: the frequency of the root crossing at `c*` (0 for a real root).
    pub crossing_frequency_rad_s: Option<f64>,
    /// The scales at which the network synchronizes, as `[from, to]` intervals inside the
    /// searched range (`to` = `searched_up_to` when still stable there).
    pub stable_scales: Vec<[f64; 2]>,
    /// The scales at which a root crosses the axis, in increasing order.
    pub crossings: Vec<f64>,
    /// The smallest stable scale, when the network is unstable for small `c`.
    pub stable_from: Option<f64>,
    /// The scale the search stopped at.
    pub searched_up_to: f64,
    /// The paper's largest certified scale `c_cert` (Theorem 1 / 1+), when it applies.
    pub reference_gain_scale: Option<f64>,
    /// `c*/c_cert`.
    pub conservatism_ratio: Option<f64>,
    /// Generalized Nyquist check at `(c*, ω*)`: smallest over largest singular value of
    /// `I/c* + H diag(W(iω*))` (0 when `−1/c*` is exactly an eigenvalue).
    pub nyquist_residual: Option<f64>,
    /// Found and checked: the Nyquist residual below `1e-9`.
    pub certified: bool,
}

/// The exact analysis of a rational network.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LinearNetworkReport {
    /// How the roots were found.
    pub method: &'static str,
    /// Roots at `c = 1`.
    pub roots: LinearRoots,
    /// Scales.
    pub critical: Option<LinearCritical>,
}

/// Why a linear network has no exact analysis here.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LinearAnalysisError {
    /// Delayed agents other than delayed integrators.
    #[error("agent {agent} (model.agents[{agent}]) has a delay of {delay_s} s and is not an integrator (η and ρ constants): exact stability of networks of delayed rational agents is not available yet; `syncroad check` certifies them (Theorem 1/1+ with a rigorous index bound), and the run measures them")]
    DelayedRational {
        /// The agent.
        agent: usize,
        /// Its delay.
        delay_s: f64,
    },
    /// The algebraic loop of biproper agents has no solution at this scale.
    #[error("I + c·D·H is singular at c = {scale}: the feedthroughs of the biproper agents (deg η = deg ρ + 1) close an algebraic loop with no solution")]
    IllPosed {
        /// The scale.
        scale: f64,
    },
    /// The eigenvalue iteration did not converge, even after diagonal similarity transforms.
    #[error(
        "the eigenvalue iteration of the closed loop did not converge at gain scale c = {scale}"
    )]
    EigenvaluesFailed {
        /// The scale.
        scale: f64,
    },
    /// Too large for dense eigenvalues.
    #[error("the closed loop has order {order} (Σ of the agents' orders deg ρ_i + 1); exact stability solves dense eigenvalue problems up to order {limit}")]
    TooLarge {
        /// Σ orders.
        order: usize,
        /// [`MAX_ORDER_TOTAL`].
        limit: usize,
    },
}

/// Largest closed-loop order the analysis takes (dense eigenvalues, about 2 s at the limit).
pub const MAX_ORDER_TOTAL: usize = 1200;

/// The network's matrices: stacked realisations and `H`.
struct Network {
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    c: DMatrix<f64>,
    d: DVector<f64>,
    h: DMatrix<f64>,
    transfers: Vec<Transfer>,
    leader: bool,
}

impl Network {
    fn new(m: &LinearModel) -> Self {
        let n = m.agents.len();
        let parts: Vec<_> = m.agents.iter().map(|a| a.realization()).collect();
        let order: usize = parts.iter().map(|p| p.0.nrows()).sum();
        let (mut a, mut b, mut c) = (
            DMatrix::zeros(order, order),
            DMatrix::zeros(order, n),
            DMatrix::zeros(n, order),
        );
        let mut d = DVector::zeros(n);
        let mut o = 0;
        for (i, (ai, bi, ci, di)) in parts.iter().enumerate() {
            let k = ai.nrows();
            a.view_mut((o, o), (k, k)).copy_from(ai);
            for r in 0..k {
                b[(o + r, i)] = bi[r];
                c[(i, o + r)] = ci[r];
            }
            d[i] = *di;
            o += k;
        }
        let mut h = m.graph.laplacian_dense();
        if let Some((_, pin)) = &m.leader {
            for (i, p) in pin.iter().enumerate() {
                h[(i, i)] += p;
            }
        }
        Self {
            a,
            b,
            c,
            d,
            h,
            transfers: m.agents.iter().map(|a| a.transfer.clone()).collect(),
            leader: m.leader.is_some(),
        }
    }

    fn closed_loop(&self, scale: f64) -> Result<DMatrix<f64>, LinearAnalysisError> {
        let n = self.h.nrows();
        let ch = &self.h * scale;
        let gain = if self.d.iter().all(|&x| x == 0.0) {
            ch
        } else {
            let m = DMatrix::identity(n, n) + DMatrix::from_diagonal(&self.d) * &ch;
            let inv = m
                .try_inverse()
                .ok_or(LinearAnalysisError::IllPosed { scale })?;
            ch * inv
        };
        Ok(&self.a - &self.b * gain * &self.c)
    }

    /// The roots at `scale`, the consensus root removed.
    fn roots(&self, scale: f64) -> Result<Vec<Complex64>, LinearAnalysisError> {
        let mut r = eigenvalues(self.closed_loop(scale)?)
            .ok_or(LinearAnalysisError::EigenvaluesFailed { scale })?;
        if !self.leader && !r.is_empty() {
            let k = (0..r.len())
                .min_by(|&i, &j| r[i].norm().total_cmp(&r[j].norm()))
                .unwrap_or(0);
            r.remove(k);
        }
        r.sort_by(|x, y| y.re.total_cmp(&x.re).then(y.im.total_cmp(&x.im)));
        Ok(r)
    }

    fn abscissa(&self, scale: f64) -> Result<(f64, f64), LinearAnalysisError> {
        let r = self.roots(scale)?;
        Ok(r.first()
            .map_or((f64::NEG_INFINITY, 0.0), |z| (z.re, z.im.abs())))
    }

    /// `arg P_c(iω) − arg (iω)^z` by LU, `z` = 1 without a leader (the consensus root).
    fn phase(&self, scale: f64, omega: f64) -> f64 {
        let n = self.h.nrows();
        let s = Complex64::new(0.0, omega);
        let mut m = DMatrix::<Complex64>::zeros(n, n);
        for i in 0..n {
            let (num, den) = self.transfers[i].eval_parts(s);
            for j in 0..n {
                m[(i, j)] = num * self.h[(i, j)] * scale;
            }
            m[(i, i)] += den;
        }
        let lu = m.lu();
        let u = lu.u();
        let mut arg: f64 = (0..n).map(|k| u[(k, k)].arg()).sum();
        if lu.p().determinant::<f64>() < 0.0 {
            arg += std::f64::consts::PI;
        }
        if !self.leader {
            arg -= std::f64::consts::FRAC_PI_2;
        }
        arg
    }

    /// Roots right of the axis by the argument principle on `[ω_lo, ω_hi]`, `None` when the
    /// total phase is not within 0.1 rad of a multiple of π/2.
    fn count_unstable(&self, scale: f64, degree: usize, roots: &[Complex64]) -> Option<usize> {
        let norms = roots.iter().map(|z| z.norm()).filter(|&x| x > 0.0);
        let big = norms.clone().fold(1.0f64, f64::max);
        let small = norms.fold(f64::INFINITY, f64::min).min(1.0);
        let (lo, hi) = (small * 1e-7, big * 1e7);
        let decades = (hi / lo).log10().ceil() as usize;
        let points = decades * 24;
        let mut grid: Vec<f64> = (0..=points)
            .map(|k| lo * (hi / lo).powf(k as f64 / points as f64))
            .collect();
        // Near a root close to the axis the phase turns by π within |Re z| of Im z, and a
        // cluster of such roots could turn it by 2π between two grid points unseen: sample
        // every root's neighbourhood at a quarter of its distance to the axis.
        for z in roots.iter().filter(|z| z.im >= 0.0) {
            let d = z.re.abs().max(1e-12 * big);
            for j in -24..=24 {
                let w = z.im + 0.25 * d * f64::from(j);
                if w > lo && w < hi {
                    grid.push(w);
                }
            }
        }
        grid.sort_by(f64::total_cmp);
        grid.dedup();
        let points = grid.len() - 1;
        let phases: Vec<f64> = grid.iter().map(|&w| self.phase(scale, w)).collect();
        let total: f64 = (0..points)
            .map(|k| self.turn(scale, (grid[k], phases[k]), (grid[k + 1], phases[k + 1]), 0))
            .sum();
        let m = degree as f64 - if self.leader { 0.0 } else { 1.0 };
        let quarter = total / std::f64::consts::FRAC_PI_2;
        let snapped = quarter.round();
        if (quarter - snapped).abs() > 0.1 * 2.0 / std::f64::consts::PI {
            return None;
        }
        let right = (m - snapped) / 2.0;
        (right >= 0.0 && right.fract() == 0.0).then_some(right as usize)
    }

    /// The phase turned from `a` to `b` (each `(ω, phase)`), bisected until each step turns
    /// less than π/4.
    fn turn(&self, scale: f64, a: (f64, f64), b: (f64, f64), depth: usize) -> f64 {
        let t = std::f64::consts::TAU;
        let d = b.1 - a.1;
        let d = d - t * ((d + std::f64::consts::PI) / t).floor();
        if d.abs() < std::f64::consts::FRAC_PI_4 || depth > 40 {
            return d;
        }
        let mid = (a.0 * b.0).sqrt();
        let m = (mid, self.phase(scale, mid));
        self.turn(scale, a, m, depth + 1) + self.turn(scale, m, b, depth + 1)
    }

    /// Generalized Nyquist residual at `(c, ω)`.
    fn nyquist_residual(&self, scale: f64, omega: f64) -> f64 {
        let n = self.h.nrows();
        let s = Complex64::new(0.0, omega.max(1e-300));
        let mut m = DMatrix::<Complex64>::zeros(n, n);
        for j in 0..n {
            let w = self.transfers[j].eval(s);
            for i in 0..n {
                m[(i, j)] = Complex64::new(self.h[(i, j)], 0.0) * w;
            }
        }
        for i in 0..n {
            m[(i, i)] += Complex64::new(1.0 / scale, 0.0);
        }
        let sv = m.singular_values();
        let (lo, hi) = sv
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
        lo / hi
    }
}

/// The eigenvalues of `a` by the capped Francis iteration; where it stalls (the exactly
/// repeated roots of symmetric graphs can make it cycle), again after a similarity by a
/// fixed diagonal scaling, which keeps the spectrum and changes the iteration's path.
fn eigenvalues(a: DMatrix<f64>) -> Option<Vec<Complex64>> {
    let n = a.nrows();
    let cap = 10_000 * n.max(1);
    for attempt in 0..4u32 {
        let m = if attempt == 0 {
            a.clone()
        } else {
            let mut rng = crate::rng::SplitMix64::new(0x5eed + u64::from(attempt));
            let d: Vec<f64> = (0..n).map(|_| 2f64.powf(rng.symmetric(1.0))).collect();
            DMatrix::from_fn(n, n, |i, j| a[(i, j)] * d[i] / d[j])
        };
        if let Some(e) = super::schur_eigenvalues::schur_eigenvalues(m, f64::EPSILON, cap) {
            return Some(e);
        }
    }
    None
}

/// The scales searched: `10^k` for k = −6..6 (each a dense eigenvalue solve of the closed
/// loop, the analysis's main cost).
const GRID: std::ops::RangeInclusive<i32> = -6..=6;

/// Analyses a delay-free rational network at its gains and over gain scales.
///
/// # Errors
/// [`LinearAnalysisError`]: delayed rational agents, an ill-posed algebraic loop, a network
/// too large.
pub fn analyse_linear(
    m: &LinearModel,
    reference_gain_scale: Option<f64>,
) -> Result<LinearNetworkReport, LinearAnalysisError> {
    if let Some((agent, a)) = m
        .agents
        .iter()
        .enumerate()
        .find(|(_, a)| a.transfer.delay_s > 0.0)
    {
        return Err(LinearAnalysisError::DelayedRational {
            agent,
            delay_s: a.transfer.delay_s,
        });
    }
    let net = Network::new(m);
    let order = net.a.nrows();
    if order > MAX_ORDER_TOTAL {
        return Err(LinearAnalysisError::TooLarge {
            order,
            limit: MAX_ORDER_TOTAL,
        });
    }
    let roots = net.roots(1.0)?;
    let abscissa = roots.first().map_or(f64::NEG_INFINITY, |z| z.re);
    let scale_of = roots.iter().fold(1.0f64, |s, z| s.max(z.norm()));
    let tol = 1e-10 * scale_of;
    let unstable = roots.iter().filter(|z| z.re > 0.0).count();
    let on_axis = roots.iter().any(|z| z.re.abs() <= tol);
    let counted = net.count_unstable(1.0, order, &roots);
    let roots_report = LinearRoots {
        dimension: order,
        abscissa,
        roots: roots
            .iter()
            .take(12)
            .map(|z| LinearRoot { re: z.re, im: z.im })
            .collect(),
        unstable_roots: unstable,
        counted_unstable_roots: counted,
        certified: counted == Some(unstable) && !on_axis,
    };
    let critical = scales(&net, reference_gain_scale)?;
    Ok(LinearNetworkReport {
        method: "closed-loop eigenvalues of the agents' realisations; root count by the argument principle on det(diag(sρ_i) + c·diag(η_i)·H)",
        roots: roots_report,
        critical: Some(critical),
    })
}

/// The stable scales, their crossings refined, `c*` and `ω*`.
fn scales(net: &Network, reference: Option<f64>) -> Result<LinearCritical, LinearAnalysisError> {
    let grid: Vec<f64> = GRID.map(|k| 10f64.powi(k)).collect();
    let mut values = Vec::with_capacity(grid.len());
    for &c in &grid {
        values.push(net.abscissa(c)?.0);
    }
    let mut crossings = Vec::new();
    for k in 0..grid.len() - 1 {
        if (values[k] < 0.0) != (values[k + 1] < 0.0) {
            crossings.push(refine(net, grid[k], grid[k + 1], values[k] < 0.0)?);
        }
    }
    let top = *grid.last().unwrap_or(&1.0);
    let mut stable_scales = Vec::new();
    let mut from = (values[0] < 0.0).then_some(0.0);
    for &c in &crossings {
        match from.take() {
            Some(f) => stable_scales.push([f, c]),
            None => from = Some(c),
        }
    }
    if let Some(f) = from {
        stable_scales.push([f, top]);
    }
    let first = stable_scales.first().copied();
    let critical_gain_scale = first.filter(|iv| iv[1] < top).map(|iv| iv[1]);
    let stable_from = first.map(|iv| iv[0]).filter(|&f| f > 0.0);
    let (omega, residual) = match critical_gain_scale {
        Some(c) => {
            let w = net.abscissa(c)?.1;
            (Some(w), Some(net.nyquist_residual(c, w)))
        }
        None => (None, None),
    };
    Ok(LinearCritical {
        critical_gain_scale,
        crossing_frequency_rad_s: omega,
        stable_scales,
        crossings,
        stable_from,
        searched_up_to: top,
        reference_gain_scale: reference,
        conservatism_ratio: critical_gain_scale.zip(reference).map(|(c, r)| c / r),
        nyquist_residual: residual,
        certified: residual.is_some_and(|r| r < 1e-9),
    })
}

/// The scale in `[lo, hi]` where the abscissa changes sign (`stable_lo`: negative at `lo`):
/// bisection in `log c` to `1e-2` relative, then Illinois regula falsi to `1e-13`.
fn refine(net: &Network, lo: f64, hi: f64, stable_lo: bool) -> Result<f64, LinearAnalysisError> {
    let f = |c: f64| -> Result<f64, LinearAnalysisError> {
        let a = net.abscissa(c)?.0;
        Ok(if stable_lo { a } else { -a })
    };
    let (mut a, mut b) = (lo, hi);
    let (mut fa, mut fb) = (f(a)?, f(b)?);
    while b / a > 1.0 + 1e-2 {
        let m = (a * b).sqrt();
        let fm = f(m)?;
        if fm < 0.0 {
            a = m;
            fa = fm;
        } else {
            b = m;
            fb = fm;
        }
    }
    // Illinois regula falsi: keeps the bracket, converges superlinearly.
    let mut side = 0;
    for _ in 0..60 {
        if (b - a) <= 1e-13 * b {
            break;
        }
        let c = (a * fb - b * fa) / (fb - fa);
        let c = if c > a && c < b { c } else { 0.5 * (a + b) };
        let fc = f(c)?;
        if fc == 0.0 {
            return Ok(c);
        }
        if fc < 0.0 {
            a = c;
            fa = fc;
            if side == -1 {
                fb /= 2.0;
            }
            side = -1;
        } else {
            b = c;
            fb = fc;
            if side == 1 {
                fa /= 2.0;
            }
            side = 1;
        }
    }
    Ok(if fa.abs() < fb.abs() { a } else { b })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::agents::LinearAgentSpec;
    use crate::graph::Graph;
    use crate::model::GraphShape;
    use approx::assert_relative_eq;

    fn all_to_all(n: usize, kappa: f64, p: f64, q: f64) -> LinearModel {
        let a = LinearAgentSpec::Transfer {
            eta: vec![1.0],
            rho: vec![q, p, 1.0],
            delay_s: 0.0,
        }
        .validate()
        .unwrap();
        LinearModel {
            graph: Graph::all_to_all(n, &vec![kappa; n]).unwrap(),
            agents: vec![a; n],
            delay_steps: vec![0; n],
            leader: None,
            shape: GraphShape::Other,
        }
    }

    #[test]
    fn remark_weak_all_to_all_crosses_at_kappa_n_equal_pq() {
        // Every non-consensus mode is s³ + p s² + q s + cκN = 0: Routh–Hurwitz gives
        // c* = pq/(κN), crossing at ω* = √q. The remark's κ(N − 1) < pq would admit more.
        let (n, kappa, p, q) = (3, 0.5, 1.0, 2.0);
        let r = analyse_linear(&all_to_all(n, kappa, p, q), None).unwrap();
        let crit = r.critical.unwrap();
        let c_star = crit.critical_gain_scale.unwrap();
        assert_relative_eq!(c_star, p * q / (kappa * n as f64), max_relative = 1e-9);
        assert_relative_eq!(
            crit.crossing_frequency_rad_s.unwrap(),
            q.sqrt(),
            max_relative = 1e-9
        );
        assert!(crit.certified, "{crit:?}");
        // κN = 1.5 < pq = 2: stable at c = 1, with N − 1 = 2 modes of multiplicity 2 each.
        assert!(r.roots.abscissa < 0.0 && r.roots.certified, "{:?}", r.roots);
        assert_eq!(r.roots.counted_unstable_roots, Some(0));
        // Beyond c*: two roots right of the axis per mode, counted by the argument principle.
        let net = Network::new(&all_to_all(n, kappa * 1.5, p, q));
        let roots = net.roots(1.0).unwrap();
        assert_eq!(roots.iter().filter(|z| z.re > 0.0).count(), 4);
        assert_eq!(net.count_unstable(1.0, 9, &roots), Some(4));
    }
}
