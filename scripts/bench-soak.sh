#!/usr/bin/env bash
# Long-run memory, sampled every few seconds (resident set size of the syncroad process and of
# its SUMO workers):
#   bash scripts/bench-soak.sh run     one 2000-vehicle run of an hour of traffic on the 20 km
#                                      ring (36 000 steps of 0.1 s)
#   bash scripts/bench-soak.sh sweep   a 1000-point sweep of the Sugiyama ring (100 gains × 10
#                                      seeds, 300 s each, no plots) on long-lived workers
#   bash scripts/bench-soak.sh         both
#   bash scripts/bench-soak.sh summary run|sweep   the summary of the last samples again
# Prints the samples' first, middle and last RSS of the parent and the workers and the growth
# of each from the first quarter of the run to its end.
set -euo pipefail
cd "$(dirname "$0")/.."
repo="$(pwd)"
bin="$repo/target/release/syncroad"
d="${TMPDIR:-/tmp}/syncroad-bench-soak"
every="${SOAK_SAMPLE_S:-5}"
mkdir -p "$d"

# rss KB of a pid and of all its children (the workers), "parent workers"
rss() {
    local p="$1" kids w=0 k
    kids="$(pgrep -P "$p" || true)"
    for k in $kids; do w=$((w + $(ps -o rss= -p "$k" 2>/dev/null || echo 0))); done
    echo "$(ps -o rss= -p "$p" 2>/dev/null || echo 0) $w"
}

# Runs the command in the background and samples it until it ends; $1 names the case.
soak() {
    local name="$1"; shift
    local log="$d/$name.rss"
    : > "$log"
    local t0; t0=$(date +%s)
    "$@" > "$d/$name.out" 2>&1 &
    local pid=$!
    while kill -0 "$pid" 2>/dev/null; do
        echo "$(( $(date +%s) - t0 )) $(rss "$pid")" >> "$log"
        sleep "$every"
    done
    # Exit 1 is a verdict (a 2000-vehicle ring does not synchronize within the tolerance in an
    # hour); anything above is a failure.
    local rc=0
    wait "$pid" || rc=$?
    if [ "$rc" -gt 1 ]; then
        echo "$name: the command failed (exit $rc); see $d/$name.out" >&2
        tail -5 "$d/$name.out" >&2
        return 1
    fi
    summary "$name" "$log"
}

# The samples' summary of case $1 from its log $2.
summary() {
    local name="$1" log="$2"
    awk -v name="$name" '
        $2 > 0 { n++; t[n] = $1; p[n] = $2; w[n] = $3; if ($3 > 0) lw = n }
        END {
            if (n < 4) { printf "%s: too short to sample (%d samples)\n", name, n; exit }
            q = int(n / 4) + 1; m = int(n / 2) + 1
            printf "%s: %d samples over %d s\n", name, n, t[n]
            printf "  parent  RSS MB: first %.0f, quarter %.0f, middle %.0f, last %.0f (quarter to last %+.1f %%)\n",
                p[1] / 1024, p[q] / 1024, p[m] / 1024, p[n] / 1024, 100 * (p[n] - p[q]) / p[q]
            # The last workers sample is the last one taken while a worker was still running.
            if (w[q] > 0)
                printf "  workers RSS MB: first %.0f, quarter %.0f, middle %.0f, last %.0f (quarter to last %+.1f %%)\n",
                    w[1] / 1024, w[q] / 1024, w[m] / 1024, w[lw] / 1024, 100 * (w[lw] - w[q]) / w[q]
        }' "$log"
}

run_case() {
    cat > "$d/ring-2000-hour.json" <<JSON
{"name": "soak-2000-hour", "backend": "sumo", "seed": 1, "step_s": 0.1, "horizon_s": 3600,
 "vehicles": 2000, "road": {"type": "ring", "length_m": 20000},
 "model": {"type": "delayed_driver", "graph": {"type": "unidirectional_ring", "gain": 0.5},
           "delay_s": 0.5},
 "initial": {"speed_mps": 10.0, "perturbation": {"speed_mps": 0.5}},
 "sumo": {"net": "$repo/sumo-nets/ring-20km.net.xml", "timeout_s": 7200}}
JSON
    rm -rf "$d/run-out"
    # The parent keeps the recorded rows (about 2000 samples of 2000 vehicles: speeds, positions
    # and commands, 96 MB) and the speed range of every step; the worker keeps nothing.
    soak run "$bin" run "$d/ring-2000-hour.json" --out "$d/run-out" --no-plots
    rows_held
}

# What the parent's rows must take: samples × vehicles × (speed, position, command) × 8 bytes.
rows_held() {
    local lines
    lines=$(wc -l < "$d/run-out/trajectories.csv")
    awk -v l="$lines" 'BEGIN { printf "  rows the parent holds by design: %d samples × 2000 vehicles × 3 values × 8 B = %.1f MB\n", (l - 1) / 2000, (l - 1) * 24 / 1048576 }'
}

sweep_case() {
    local values
    values="$(python3 -c 'print(", ".join(f"{0.4 + 0.004 * k:.3f}" for k in range(100)))')"
    cat > "$d/spec.json" <<JSON
{"name": "soak", "base": "$repo/scenarios/sugiyama-ring.json", "backend": "sumo",
 "axes": [{"field": "model.graph.gain_pred", "values": [$values]}],
 "seeds": [1, 2, 3, 4, 5, 6, 7, 8, 9, 10], "metrics": ["sync.verdict", "sync.final_spread_mps"]}
JSON
    rm -rf "$d/sweep-out"
    soak sweep "$bin" sweep "$d/spec.json" --out "$d/sweep-out" --no-plots
}

case "${1:-both}" in
    summary) summary "${2:?summary run|sweep}" "$d/${2}.rss"; if [ "$2" = run ]; then rows_held; fi ;;
    run) run_case ;;
    sweep) sweep_case ;;
    both) run_case; sweep_case ;;
    *) echo "usage: bench-soak.sh [run|sweep|both]" >&2; exit 2 ;;
esac
