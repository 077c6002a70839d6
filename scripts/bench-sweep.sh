#!/usr/bin/env bash
# Sweep throughput against a shell loop, on the same 200 Sugiyama-ring points in SUMO
# (20 values of gain_pred × 10 seeds, 300 s each, no plots):
#   bash scripts/bench-sweep.sh sweep   one `syncroad sweep` (long-lived SUMO workers, all cores)
#   bash scripts/bench-sweep.sh loop    a shell loop of `syncroad run` per point (one at a time)
#   bash scripts/bench-sweep.sh loop2   the same loop, two points at a time (xargs -P 2)
#   bash scripts/bench-sweep.sh bound   the stepping bound: the time inside SUMO's step of
#                                       every point's run (one worker, `syncroad sumo-bench
#                                       --step-time`), summed and divided by the cores
# Side by side, as the guide's performance chapter (docs/src/performance.md) quotes it (sweep
# and loop in turn, PAIRS times; medians and the ratio of each pair; then the bound and the
# sweep's ratio to it):
#   bash scripts/bench-sweep.sh vs loop 2      (or: vs loop2 2)
set -euo pipefail
cd "$(dirname "$0")/.."
repo="$(pwd)"
bin="$repo/target/release/syncroad"
d="${TMPDIR:-/tmp}/syncroad-bench-sweep"
mode="${1:?usage: bench-sweep.sh sweep|loop|loop2|bound|vs loop|loop2 [PAIRS]}"
cores="$(nproc)"
if [ "$mode" = vs ]; then
    other="${2:?vs needs loop or loop2}"
    pairs="${3:-2}"
    for i in $(seq "$pairs"); do
        t0=$(date +%s.%N); bash "$0" sweep >/dev/null 2>&1; t1=$(date +%s.%N)
        bash "$0" "$other" >/dev/null 2>&1; t2=$(date +%s.%N)
        echo "$t0 $t1 $t2"
    done | awk -v other="$other" '
        { a[NR] = $2 - $1; b[NR] = $3 - $2; r[NR] = a[NR] / b[NR];
          printf "pair %d: sweep %.1f s, %s %.1f s, ratio %.3f\n", NR, a[NR], other, b[NR], r[NR] }
        function median(x, n,   i, j, t) {
            for (i = 1; i <= n; i++) for (j = i + 1; j <= n; j++) if (x[j] < x[i]) { t = x[i]; x[i] = x[j]; x[j] = t }
            return n % 2 ? x[(n + 1) / 2] : (x[n / 2] + x[n / 2 + 1]) / 2 }
        END { n = NR; ma = median(a, n); mb = median(b, n); mr = median(r, n);
              printf "median: sweep %.1f s (%.2f runs/s), %s %.1f s (%.2f runs/s); sweep/%s wall %.3f (%.1fx faster)\n",
                     ma, 200 / ma, other, mb, 200 / mb, other, mr, 1 / mr
              print ma > "'"$d/sweep-median"'" }'
    bound="$(bash "$0" bound | awk '/^bound/ { print $2 }')"
    awk -v s="$(cat "$d/sweep-median")" -v b="$bound" -v c="$cores" \
        'BEGIN { printf "stepping bound: %.1f s (time inside the SUMO step over the 200 points / %d cores); sweep/bound %.2f\n", b, c, s / b }'
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
    bound) "$bin" sumo-bench --step-time $(seq -f "$d/points/%g.json" 0 199) 2>/dev/null \
               | awk -v c="$cores" '$1 == "total" { printf "inside simulation.step over the points: %.2f s\nbound %.3f s on %d cores\n", $2, $2 / c, c }' ;;
    *) echo "usage: bench-sweep.sh sweep|loop|loop2|bound" >&2; exit 2 ;;
esac
