//! Human-readable tables: the theory report, a run's summary, its congestion lines.

use std::fmt::Write as _;

use syncroad_control::congestion::CongestionMetrics;
use syncroad_control::metrics::SyncMetrics;
use syncroad_control::theory::{Binding, TheoryReport};
use syncroad_control::Scenario;

fn yes(b: bool) -> &'static str {
    if b {
        "yes"
    } else {
        "NO"
    }
}

fn binding_line(out: &mut String, label: &str, b: &Binding) {
    // The relation as it holds, not as required: "0.96 ≥ 0.5" when the bound is violated.
    let relation = if b.margin > 0.0 { "<" } else { "≥" };
    let _ = writeln!(
        out,
        "  {label:<38} vehicle {:>5}: {:.6} {relation} {:.6}  (margin {:+.6})",
        b.vehicle, b.value, b.bound, b.margin
    );
}

/// Per-vehicle rows `value, margin to 1/2` (and `p_j`) for scenarios of at most 30 vehicles.
fn per_vehicle(out: &mut String, label: &str, values: &[f64], p: Option<&[f64]>) {
    if values.len() > 30 {
        return;
    }
    let _ = writeln!(
        out,
        "  {:>7}  {:>12}  {:>12}{}",
        "vehicle",
        label,
        "margin",
        if p.is_some() { "           p_j" } else { "" }
    );
    for (j, v) in values.iter().enumerate() {
        let pj = p.map_or(String::new(), |p| format!("  {:>12.6}", p[j]));
        let _ = writeln!(out, "  {j:>7}  {v:>12.6}  {:>+12.6}{pj}", 0.5 - v);
    }
}

/// The agents and their IFP indices: every distinct agent, at most 12 rows.
fn agents_table(s: &mut String, r: &TheoryReport) {
    if r.agents.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "\nagents W_i = η_i/(s ρ_i) · e^(−s τ_i) and their IFP index α_i:"
    );
    let mut shown = 0;
    let mut last: Option<usize> = None;
    for (i, a) in r.agents.iter().enumerate() {
        if last.is_some_and(|j| r.agents[j].transfer == a.transfer) {
            continue;
        }
        let same = r.agents[i..]
            .iter()
            .take_while(|b| b.transfer == a.transfer)
            .count();
        last = Some(i);
        shown += 1;
        if shown > 12 {
            let _ = writeln!(
                s,
                "  ... more agents (syncroad check --json lists every one)"
            );
            break;
        }
        let who = if same > 1 {
            format!("{i}..{}", i + same - 1)
        } else {
            i.to_string()
        };
        let index = match (a.ifp_index, &a.hypothesis_failed) {
            (Some(x), _) => format!(
                "α = {x:.10}{}",
                if a.exact == Some(true) {
                    " (exact)".to_string()
                } else {
                    format!(
                        " (upper bound; ≥ {:.10})",
                        a.lower_bound.unwrap_or(f64::NAN)
                    )
                }
            ),
            (None, Some(h)) => format!("not IFP: {h}"),
            (None, None) => "—".to_string(),
        };
        let _ = writeln!(
            s,
            "  {who:>9}  η {:?}  ρ {:?}  τ {} s  {index}",
            a.transfer.eta, a.transfer.rho, a.transfer.delay_s
        );
    }
    if let Some(n) = &r.not_applicable {
        let _ = writeln!(s, "\nTheorems 1 and 1+ do not apply: {n}");
    }
}

/// The `syncroad check` table.
/// The paper's conditions for the scenario's model, and the verdict; `otherwise`: what drives
/// the scenario's runs instead of the model's law on every vehicle (then the scenario is not
/// certified, whatever the conditions say of the model's law).
pub fn theory_table(r: &TheoryReport, otherwise: Option<&str>) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "scenario {}: {} vehicles", r.scenario, r.vehicles);
    let g = &r.graph;
    let _ = writeln!(
        s,
        "graph: {} arcs, strongly connected: {}, spanning-tree root: {}",
        g.arcs,
        yes(g.strongly_connected),
        g.spanning_tree_root
            .map_or("none".to_string(), |x| x.to_string())
    );
    agents_table(&mut s, r);
    if let Some(t) = &r.theorem1 {
        let _ = writeln!(
            s,
            "\nTheorem 1 (strongly connected, α_j d_j^+ < 1/2): {}",
            if t.holds { "HOLDS" } else { "does not hold" }
        );
        let _ = writeln!(
            s,
            "  strongly connected                     {}",
            yes(t.strongly_connected)
        );
        binding_line(&mut s, "binding α_j d_j^+", &t.binding);
        let _ = writeln!(
            s,
            "  largest gain scale c keeping it        {:.6}",
            t.max_gain_scale
        );
        if let Some(p) = &t.left_null_vector {
            let (lo, hi) = p
                .iter()
                .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
            let _ = writeln!(
                s,
                "  left null vector p (Σp = 1)            min {lo:.6}, max {hi:.6}"
            );
        }
        per_vehicle(
            &mut s,
            "α_j d_j^+",
            &t.products,
            t.left_null_vector.as_deref(),
        );
    }
    if let Some(t) = &r.theorem1_plus {
        let _ = writeln!(
            s,
            "\nTheorem 1+ (α_j (d_j^+ + 2 b_j) < 1/2, Σ b_j > 0): {}",
            if t.holds { "HOLDS" } else { "does not hold" }
        );
        let _ = writeln!(
            s,
            "  strongly connected                     {}",
            yes(t.strongly_connected)
        );
        let _ = writeln!(
            s,
            "  Σ b_j                                  {:.6}",
            t.pinning_sum
        );
        binding_line(&mut s, "binding α_j (d_j^+ + 2 b_j)", &t.binding);
        per_vehicle(&mut s, "α_j(d+2b)", &t.products, None);
        let _ = writeln!(
            s,
            "  largest gain scale c keeping it        {:.6}",
            t.max_gain_scale
        );
    }
    if let Some(c) = &r.cacc {
        let _ = writeln!(
            s,
            "\nCACC theorem (μ_i τ_i < 1/2, eq. constants-vehi): {}",
            if c.holds { "HOLDS" } else { "does not hold" }
        );
        binding_line(&mut s, "binding μ_i τ_i", &c.lag_binding);
        binding_line(&mut s, "binding gain sum vs μ_i²/2", &c.gain_binding);
        let (lo, hi) = c
            .ifp_index
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
        let _ = writeln!(s, "  IFP index of the agents (Lemma)        min {lo:.6}, max {hi:.6}  (1/μ_i² when μ_i τ_i ≤ 1/2)");
        if let Some(v) = &c.via_theorem1_plus {
            let _ = writeln!(
                s,
                "  via Theorem 1+ with those indices      {}",
                yes(v.holds)
            );
        }
    }
    if let Some(c) = &r.chandler {
        let _ = writeln!(
            s,
            "\nChandler (uniform predecessor following): 2αK = {:.6} {} 1  → {}",
            c.two_alpha_k,
            if c.holds { "<" } else { "≥" },
            if c.holds { "holds" } else { "does not hold" }
        );
    }
    s.push_str(&verdict_line(r, otherwise));
    s
}

/// The verdict line of [`theory_table`]: certified or not, and for a scenario another driver
/// runs (`otherwise`), that it is not certified whatever the conditions say of the model.
fn verdict_line(r: &TheoryReport, otherwise: Option<&str>) -> String {
    let mut s = String::new();
    match otherwise {
        None => {
            let _ = writeln!(
                s,
                "\nverdict: synchronization {}",
                if r.certified {
                    "CERTIFIED by the paper's sufficient conditions"
                } else {
                    "NOT certified (the conditions are sufficient, not necessary)"
                }
            );
        }
        Some(why) => {
            let _ = writeln!(
                s,
                "\nverdict: this scenario is NOT certified: {why}; the conditions above are of the model's law on every vehicle, which they {}",
                if r.certified {
                    "certify"
                } else {
                    "do not certify"
                }
            );
        }
    }
    s
}

/// A measured figure, or "—" when nothing was measured.
fn num(x: Option<f64>, f: impl Fn(f64) -> String) -> String {
    x.map_or("—".to_string(), f)
}

fn opt(x: Option<f64>, unit: &str) -> String {
    x.map_or("—".to_string(), |v| format!("{v:.6} {unit}"))
}

/// The spread of the scenario's vehicles' speeds, line by line.
fn spread_lines(s: &mut String, m: &SyncMetrics) {
    let vs = if m.against_leader {
        "max_i |v_i − v_0|"
    } else {
        "max_ij |v_i − v_j|"
    };
    let _ = writeln!(
        s,
        "  spread {vs}: initial {} m/s, final {} m/s, max {} m/s",
        num(m.initial_spread_mps, |x| format!("{x:.6}")),
        num(m.final_spread_mps, |x| format!("{x:.3e}")),
        num(m.max_spread_mps, |x| format!("{x:.6}"))
    );
    let _ = writeln!(
        s,
        "  spread over the final {} s       ≤ {} m/s (tolerance {} m/s)",
        m.thresholds.window_s,
        num(m.window_max_spread_mps, |x| format!("{x:.3e}")),
        m.thresholds.tolerance_mps
    );
    let _ = writeln!(
        s,
        "  L2 norm of the spread             {} m/s·√s",
        num(m.spread_l2, |x| format!("{x:.6}"))
    );
    let _ = writeln!(
        s,
        "  time to tolerance                 {}",
        opt(m.time_to_tolerance_s, "s")
    );
    let _ = writeln!(
        s,
        "  fitted decay rate                 {}",
        opt(m.decay_rate_per_s, "1/s")
    );
    if m.final_gap_error_m.is_some() {
        let _ = writeln!(
            s,
            "  final max |gap − s_i|             {}",
            opt(m.final_gap_error_m, "m")
        );
    }
}

/// The summary printed after a run.
pub fn metrics_table(
    sc: &Scenario,
    backend: &str,
    m: &SyncMetrics,
    stopped_early: Option<&str>,
    record: &syncroad_control::record::RunRecord,
) -> String {
    let law_vehicles = record.law_controlled_vehicles;
    let graph_changed = record
        .safety
        .as_ref()
        .is_some_and(syncroad_control::sumo_facts::Safety::graph_changed);
    let mut s = String::new();
    if sc.vehicles() == 0 {
        // An open road of inflows only: no fixed set, so no spread and no certificate.
        let _ = writeln!(
            s,
            "scenario {} on {backend}: no vehicles of its own (an open road of inflows), {} s, Δt = {} s, seed {}",
            sc.name(),
            sc.horizon_s(),
            sc.step_s(),
            sc.seed()
        );
    } else {
        let _ = writeln!(
            s,
            "scenario {} on {backend}: {} vehicles, {} s, Δt = {} s, seed {}",
            sc.name(),
            sc.vehicles(),
            sc.horizon_s(),
            sc.step_s(),
            sc.seed()
        );
        spread_lines(&mut s, m);
    }
    if let Some(why) = stopped_early {
        let _ = writeln!(s, "  stopped early: {why}");
    }
    let _ = writeln!(
        s,
        "  certified by the paper's conditions: {}",
        match record.certified {
            Some(c) => yes(c).to_string(),
            None if record.controller.is_some() => format!(
                "does not apply (they are for the scenario's model law; {} drove)",
                record.controller.as_ref().map_or("", |c| c.label.as_str())
            ),
            None if sc.vehicles() == 0 => "does not apply (no vehicles of its own)".to_string(),
            None if graph_changed => {
                "does not apply (the graph changed in SUMO; the conditions are for a fixed graph)"
                    .to_string()
            }
            None if law_vehicles < sc.vehicles() => format!(
                "does not apply (the law drives {law_vehicles} of {} vehicles)",
                sc.vehicles()
            ),
            None => "does not apply (no sample)".to_string(),
        }
    );
    if let Some(l) = &record.safety_layer {
        let what = match (l.mode.name(), l.filter) {
            ("off", _) => "off (the law's commands as they are)".to_string(),
            ("sumo", _) => "sumo (SUMO's safe speed, right of way and red lights)".to_string(),
            (_, Some(f)) => format!(
                "filter (Gipps' safe speed; {} commands lowered, by up to {:.3} m/s)",
                f.overrides, f.largest_cut_mps
            ),
            (m, None) => m.to_string(),
        };
        let _ = writeln!(s, "  safety layer: {what}");
    }
    let _ = writeln!(s, "  safety: {}", safety_word(record));
    let mark = if record.safe == Some(false) {
        ", UNSAFE"
    } else {
        ""
    };
    if record.checks_nothing() {
        // Nothing to synchronize, and the run did all it was asked: not a finding (exit 0).
        let _ = writeln!(s, "verdict: none to give, the run completed{mark}");
    } else {
        let _ = writeln!(s, "verdict: {}{mark}", m.verdict);
    }
    if let Some(why) = &m.verdict_reason {
        // A synchronized verdict keeps its reasons as notes (nothing lowered it).
        let lead = if m.verdict == syncroad_control::Verdict::Synchronized {
            "note:"
        } else {
            "because"
        };
        let _ = writeln!(s, "  {lead} {why}");
    }
    s
}

/// The run's safety in a few words: `safe`, `UNSAFE (what)` or `not measured`.
pub fn safety_word(record: &syncroad_control::record::RunRecord) -> String {
    match record.safe {
        Some(true) => "safe (no collision, overlap, teleport or emergency braking)".to_string(),
        Some(false) => format!("UNSAFE ({})", record.unsafe_because.join("; ")),
        None => "not measured (SUMO's counters never arrived)".to_string(),
    }
}

/// Summary lines of the congestion metrics.
pub fn congestion_lines(c: &CongestionMetrics) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "  congestion after {} s warm-up:", c.warmup_s);
    let _ = writeln!(
        s,
        "    mean speed {:.3} m/s, harmonic mean {:.3} m/s, min {:.3} m/s",
        c.mean_speed_mps, c.harmonic_mean_speed_mps, c.min_speed_mps
    );
    let _ = writeln!(
        s,
        "    speed std {:.4} m/s (across vehicles {:.4}, over time {:.4})",
        c.speed_std_mps, c.speed_std_across_vehicles_mps, c.speed_std_over_time_mps
    );
    let _ = writeln!(
        s,
        "    stops {} ({:.2} % of vehicle-time), wave amplitude {:.3} m/s, wave speed {}",
        c.stop_events,
        100.0 * c.stopped_fraction,
        c.wave_amplitude_mps,
        opt(c.wave_speed_mps, "m/s")
    );
    s
}
