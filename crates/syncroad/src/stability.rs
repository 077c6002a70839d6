//! `syncroad stability`: the tables. The analysis itself is
//! `syncroad_control::exact::analysis`.
//!
//! * Delayed drivers: rightmost characteristic roots of `det(sI + diag(e^{−sα_i}) L) = 0`
//!   (roots other than consensus), the critical scale of all gains and of all delays, and the
//!   conservatism ratio against Theorem 1. Uniform rings of any size use the Fourier/Lambert-W
//!   fast path; other graphs the full solve (collocation + Newton, certified by the argument
//!   principle). A leader with pinning gains enters as an extra, undelayed vertex whose speed
//!   never changes, so the consensus root is the leader's own mode; when the network
//!   synchronizes, the peak gain from the leader's speed to each follower's.
//! * CACC platoons: closed-loop eigenvalues, Theorem `thm.cacc` beside the exact verdict, and
//!   string stability.

use std::fmt::Write as _;

use syncroad_control::exact::analysis::{CriticalScaleStatus, ExactVerdict, StabilityReport};
use syncroad_control::exact::PlatoonScaling;

/// The table printed by `syncroad stability`.
pub fn table(r: &StabilityReport) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "scenario {}: exact stability", r.scenario);
    if let Some(ring) = &r.ring {
        let _ = writeln!(s, "\nuniform ring, Fourier modes (Lambert W fast path):");
        let _ = write!(s, "{ring}");
    }
    if let Some(x) = &r.acyclic {
        acyclic_table(&mut s, x, r);
    }
    if let Some(c) = &r.chain_string_stability {
        let _ = writeln!(
            s,
            "string stability: worst predecessor-to-follower peak sup_ω|H_i(iω)| = {:.6} (driver {}), max 2α_i d_i = {:.6} (Chandler: string stable iff ≤ 1) -> {}",
            c.worst_peak,
            c.worst_driver,
            c.max_two_alpha_d,
            if c.string_stable {
                "string stable"
            } else {
                "string UNSTABLE: speed disturbances grow along the chain"
            }
        );
    }
    if let Some(x) = &r.leader_amplification {
        amplification_line(&mut s, x);
    }
    if let Some(n) = r.network.as_ref().and_then(|n| n.delayed()) {
        let _ = writeln!(
            s,
            "\nfull solve (Chebyshev collocation, shift-invert or dense, + Newton):"
        );
        let _ = write!(s, "{n}");
    }
    if let Some(n) = r.network.as_ref().and_then(|n| n.linear()) {
        linear_table(&mut s, n);
    }
    if let Some(g) = &r.no_spanning_tree {
        let _ = writeln!(
            s,
            "\nno directed spanning tree: no single vehicle reaches every other through the graph (vehicle {} is missed), so the consensus root s = 0 has multiplicity {} (one per group of vehicles that nobody outside it influences) and each group keeps its own speed",
            g.unreached, g.consensus_multiplicity
        );
    }
    if let Some(c) = &r.cacc {
        let _ = writeln!(s, "\nCACC platoon:");
        let _ = write!(s, "{c}");
    }
    let _ = writeln!(
        s,
        "\nexact: {}   paper's conditions: {}",
        match r.verdict {
            ExactVerdict::Synchronizes => "SYNCHRONIZES",
            ExactVerdict::DoesNotSynchronize => "does NOT synchronize",
            ExactVerdict::Uncertified =>
                "UNCERTIFIED (the root count disagrees with the computed roots; roots may have been missed)",
        },
        if r.certified {
            "certified"
        } else {
            "not certified"
        }
    );
    if r.critical_scale_status == CriticalScaleStatus::Uncertified {
        let _ = writeln!(s, "critical scale: UNCERTIFIED (the root counts at c* do not confirm that the reported root crosses first)");
    }
    if r.certified && r.verdict == ExactVerdict::DoesNotSynchronize {
        let _ = writeln!(s, "WARNING: the sufficient conditions certify a network the exact analysis finds unstable; please report this scenario.");
    }
    s
}

/// The acyclic network's per-driver roots and its critical scale against Theorem 1+.
fn acyclic_table(s: &mut String, x: &syncroad_control::exact::AcyclicReport, r: &StabilityReport) {
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
            "  ratio {:.6} to Theorem 1+ ({t:.10}, α_j(d_j^+ + 2b_j) < 1/2)",
            x.critical_gain_scale / t
        ))
    );
}

/// The worst amplification from the leader's speed to a follower's.
fn amplification_line(
    s: &mut String,
    x: &syncroad_control::exact::leader_amplification::LeaderAmplification,
) {
    let shown: Vec<String> = x.peaks.iter().take(12).map(|p| format!("{p:.4}")).collect();
    let _ = writeln!(
        s,
        "leader-to-follower amplification sup_ω|T_i(iω)|: worst {:.6} (vehicle {}, ω = {:.4} rad/s) -> {}\n  per follower: {}{}",
        x.worst_peak,
        x.worst_vehicle,
        x.worst_frequency_rad_s,
        if x.no_amplification {
            "no follower's speed overshoots the leader's"
        } else {
            "changes of the leader's speed are amplified along the platoon"
        },
        shown.join(" "),
        if x.peaks.len() > 12 {
            format!(" ... ({} followers)", x.peaks.len())
        } else {
            String::new()
        }
    );
}

/// The linear agents' roots and stable scales.
fn linear_table(s: &mut String, n: &syncroad_control::exact::linear::LinearNetworkReport) {
    let r = &n.roots;
    let _ = writeln!(
        s,
        "\nlinear agents: closed loop of order {}, rightmost roots of det(diag(sρ_i) + c·diag(η_i)·H) at c = 1 (consensus removed):",
        r.dimension
    );
    let _ = writeln!(s, "{:>14} {:>14}", "Re s [1/s]", "Im s [rad/s]");
    for z in &r.roots {
        let _ = writeln!(s, "{:>14.6e} {:>14.6e}", z.re, z.im);
    }
    let _ = writeln!(
        s,
        "spectral abscissa {:.6e} 1/s; roots right of the axis: {} by the eigenvalues, {} by the argument principle{}",
        r.abscissa,
        r.unstable_roots,
        r.counted_unstable_roots
            .map_or("— (count did not close)".to_string(), |c| c.to_string()),
        if r.certified { " (certified)" } else { " (UNCERTIFIED)" }
    );
    if let Some(c) = &n.critical {
        let intervals: Vec<String> = c
            .stable_scales
            .iter()
            .map(|iv| {
                if iv[1] >= c.searched_up_to {
                    format!("({:.6}, ≥{:.0e})", iv[0], iv[1])
                } else {
                    format!("({:.6}, {:.10})", iv[0], iv[1])
                }
            })
            .collect();
        let _ = writeln!(
            s,
            "stable gain scales c: {}",
            if intervals.is_empty() {
                format!("none up to {:.0e}", c.searched_up_to)
            } else {
                intervals.join(" ∪ ")
            }
        );
        if let Some(f) = c.stable_from {
            let _ = writeln!(
                s,
                "  unstable for small c: the network synchronizes only from c = {f:.10}"
            );
        }
        match (c.critical_gain_scale, c.crossing_frequency_rad_s) {
            (Some(cs), Some(w)) => {
                let _ = writeln!(
                    s,
                    "critical gain scale c* {cs:.10}, crossing at ω* = {w:.10} rad/s{}",
                    c.conservatism_ratio.map_or(String::new(), |q| format!(
                        "  ratio {q:.6} to the paper's c_cert = {:.10}",
                        c.reference_gain_scale.unwrap_or(f64::NAN)
                    ))
                );
                let _ = writeln!(
                    s,
                    "  generalized Nyquist check: −1/c* is an eigenvalue of H·diag(W(iω*)) to {:.1e}{}",
                    c.nyquist_residual.unwrap_or(f64::NAN),
                    if c.certified { "" } else { " (UNCERTIFIED)" }
                );
            }
            _ => {
                let _ = writeln!(
                    s,
                    "critical gain scale: none found up to c = {:.0e} (searched, not proven)",
                    c.searched_up_to
                );
            }
        }
    }
}

/// The table printed by `syncroad stability --platoon-scaling`.
pub fn scaling_table(studies: &[PlatoonScaling]) -> String {
    let mut s = String::from(
        "\nplatoon scaling: least-stable eigenvalue Re λ [1/s] against platoon size N\n",
    );
    for st in studies {
        let _ = writeln!(s, "{}", serde_json::to_string(&st.law).unwrap_or_default());
        let mut line = String::from("  ");
        for p in &st.points {
            let _ = write!(line, " N={}: {:.3e}", p.vehicles, p.least_stable_re);
        }
        let _ = writeln!(s, "{line}");
        let _ = writeln!(
            s,
            "   fitted |Re λ| ≈ {:.4} N^{:.3}",
            st.prefactor, st.exponent
        );
    }
    s
}
