#!/usr/bin/env bash
# Sweep throughput against a shell loop, on the same 200 Sugiyama-ring points in SUMO
# (20 values of gain_pred × 10 seeds, 300 s each, no plots):
#   bash scripts/bench-sweep.sh sweep   one `syncroad sweep` (long-lived SUMO workers, all cores)
#   bash scripts/bench-sweep.sh loop    a shell loop of `syncroad run` per point (one at a time)
#   bash scripts/bench-sweep.sh loop2   the same loop, two points at a time (xargs -P 2)
#   bash scripts/bench-sweep.sh bound   the stepping bound: the time inside SUMO's step of
#                                       every point's run (`syncroad sumo-bench --step-time`),
#                                       summed and divided by the cores, measured twice: one
#                                       SUMO at a time (one worker, the other cores idle), and
#                                       with every core stepping (the points split into one
#                                       share per core, stepped at once, as a sweep steps them)
# Side by side, as the guide's performance chapter (docs/src/performance.md) quotes it (sweep
# and loop in turn, PAIRS times; medians and the ratio of each pair; then the bound and the
# sweep's ratio to it):
#   bash scripts/bench-sweep.sh vs loop 2      (or: vs loop2 2)
# SYNCROAD_BIN picks another build (default target/release/syncroad), for instance the profiling
# profile's under `perf record -a`.
set -euo pipefail
cd "$(dirname "$0")/.."
repo="$(pwd)"
bin="${SYNCROAD_BIN:-$repo/target/release/syncroad}"
d="${TMPDIR:-/tmp}/syncroad-bench-sweep"
mode="${1:?usage: bench-sweep.sh sweep|loop|loop2|bound|vs loop|loop2 [PAIRS]}"
cores="$(nproc)"
if [ "$mode" = vs ]; then
    other="${2:?vs needs loop or loop2}"
    pairs="${3:-2}"
    mkdir -p "$d"
    # Each round runs the sweep, the other side and the bound in turn: this machine's speed
    # drifts over minutes, so each ratio is taken within one round.
    for i in $(seq "$pairs"); do
        t0=$(date +%s.%N); bash "$0" sweep > "$d/sweep-$i" 2>/dev/null; t1=$(date +%s.%N)
        bash "$0" "$other" >/dev/null 2>&1; t2=$(date +%s.%N)
        bash "$0" bound > "$d/bound-$i"
        # The sweep's own figure: its points' time inside SUMO's step, measured in the sweep.
        inrun="$(sed -n 's/.*inside SUMO.s step: \([0-9.]*\) s over the points.*/\1/p' "$d/sweep-$i")"
        echo "$t0 $t1 $t2 $(awk '$1 == "bound" { printf "%s ", $3 }' "$d/bound-$i") $inrun"
    done | awk -v other="$other" -v c="$cores" '
        { a[NR] = $2 - $1; b[NR] = $3 - $2; r[NR] = a[NR] / b[NR];
          ba[NR] = a[NR] / $4; bl[NR] = a[NR] / $5; bi[NR] = $6 > 0 ? a[NR] / ($6 / c) : 0;
          printf "pair %d: sweep %.1f s, %s %.1f s, ratio %.3f; bound alone %.1f s (sweep/bound %.2f), every core stepping %.1f s (sweep/bound %.2f), in the sweep itself %.1f s (sweep/bound %.2f)\n", NR, a[NR], other, b[NR], r[NR], $4, ba[NR], $5, bl[NR], $6 / c, bi[NR] }
        function median(x, n,   i, j, t) {
            for (i = 1; i <= n; i++) for (j = i + 1; j <= n; j++) if (x[j] < x[i]) { t = x[i]; x[i] = x[j]; x[j] = t }
            return n % 2 ? x[(n + 1) / 2] : (x[n / 2] + x[n / 2 + 1]) / 2 }
        END { n = NR; ma = median(a, n); mb = median(b, n); mr = median(r, n);
              printf "median: sweep %.1f s (%.2f runs/s), %s %.1f s (%.2f runs/s); sweep/%s wall %.3f (%.1fx faster)\n",
                     ma, 200 / ma, other, mb, 200 / mb, other, mr, 1 / mr
              printf "median sweep/bound: %.2f against the bound of one SUMO at a time (time inside the SUMO step over the 200 points / %d cores), %.2f against the bound with every core stepping, %.2f against the time inside the step in the sweep itself\n",
                     median(ba, n), c, median(bl, n), median(bi, n) }'
    exit 0
fi

gains=(0.40 0.42 0.44 0.46 0.48 0.50 0.52 0.54 0.56 0.58 0.60 0.62 0.64 0.66 0.68 0.70 0.72 0.74 0.76 0.78)
seeds=(1 2 3 4 5 6 7 8 9 10)
if [ ! -f "$d/points/199.json" ]; then
    mkdir -p "$d/points"
    # The per-point scenario files of the loop: the base scenario with the point's fields set.
    python3 - "$repo" "$d" "${gains[*]}" "${seeds[*]}" <<'PY'
import json, sys
repo, d, gains, seeds = sys.argv[1], sys.argv[2], sys.argv[3].split(), sys.argv[4].split()
base = json.load(open(f"{repo}/scenarios/sugiyama-ring.json"))
base["sumo"]["net"] = f"{repo}/sumo-nets/sugiyama-ring.net.xml"
k = 0
for g in gains:
    for s in seeds:
        base["model"]["graph"]["gain_pred"] = float(g)
        base["seed"] = int(s)
        json.dump(base, open(f"{d}/points/{k}.json", "w"))
        k += 1
PY
    values="$(printf '%s, ' "${gains[@]}")"
    cat > "$d/spec.json" <<JSON
{"name": "bench", "base": "$repo/scenarios/sugiyama-ring.json", "backend": "sumo",
 "axes": [{"field": "model.graph.gain_pred", "values": [${values%, }]}],
 "seeds": [$(IFS=,; echo "${seeds[*]}")], "metrics": ["sync.verdict", "sync.final_spread_mps"]}
JSON
fi
rm -rf "$d/out" && mkdir -p "$d/out"
case "$mode" in
    sweep) exec "$bin" sweep "$d/spec.json" --out "$d/out/sweep" --no-plots ;;
    loop) for k in $(seq 0 199); do "$bin" run "$d/points/$k.json" --out "$d/out/$k" --no-plots >/dev/null; done ;;
    loop2) seq 0 199 | xargs -P 2 -I{} "$bin" run "$d/points/{}.json" --out "$d/out/{}" --no-plots >/dev/null ;;
    bound)
        step_time() { "$bin" sumo-bench --step-time "$@" 2>/dev/null | awk '$1 == "total" { print $2 }'; }
        alone="$(step_time $(seq -f "$d/points/%g.json" 0 199))"
        # Every core steps a share of the points at once: SUMO's step may be slower while the
        # other cores step too (shared caches, memory, a host's hyperthreads), as in a sweep.
        for c in $(seq 0 $((cores - 1))); do
            step_time $(seq -f "$d/points/%g.json" "$c" "$cores" 199) > "$d/share-$c" &
        done
        wait
        loaded="$(cat "$d"/share-* | awk '{ s += $1 } END { print s }')"
        rm -f "$d"/share-*
        awk -v a="$alone" -v l="$loaded" -v c="$cores" 'BEGIN {
            printf "inside simulation.step over the points, one SUMO at a time: %.2f s\n", a
            printf "inside simulation.step over the points, %d cores stepping: %.2f s\n", c, l
            printf "bound alone %.3f s on %d cores\nbound loaded %.3f s on %d cores\n", a / c, c, l / c, c }' ;;
    *) echo "usage: bench-sweep.sh sweep|loop|loop2|bound" >&2; exit 2 ;;
esac
