#!/usr/bin/env bash
# Sets everything up and runs the main job: the Sugiyama ring (22 vehicles, 230 m) headlessly
# in SUMO, every driver running the delayed-driver law; prints the verdict and metrics.
set -euo pipefail
cd "$(dirname "$0")/.."
bash python-host/bootstrap.sh
cargo build --release -p syncroad
./target/release/syncroad check scenarios/sugiyama-ring.json || true
./target/release/syncroad run scenarios/sugiyama-ring.json --out out/sugiyama-ring
# The same ring with SUMO's own drivers (Krauss σ 0.5 and 0.9, IDM): side-by-side table,
# compare.json and one folder per run with plots.
./target/release/syncroad compare scenarios/sugiyama-ring.json --out out/compare
# Mixed traffic: 0, 1, 2, 4 law-driven vehicles among Krauss σ 0.9 drivers.
./target/release/syncroad compare scenarios/sugiyama-ring.json --mixed 0,1,2,4 --mixed-driver krauss-0.9 \
  --out out/compare-mixed
# The ring experiments a traffic researcher trusts: SUMO's calibrated human drivers (IDM,
# docs/src/human-preset.md) form Sugiyama's jam on the same ring within 600 s; beside them the law
# and the wave dampers of Stern et al. (2018) on every vehicle, and each damper (and the law)
# as 1, 2 or 4 automated vehicles among the humans, with SUMO's surrogate safety measures.
# FollowerStopper's desired speed U = 4.3 m/s is the humans' uniform-flow speed on this ring.
./target/release/syncroad compare scenarios/sugiyama-human.json --warmup-s 400 --ssm \
  --baselines protocol,human,follower-stopper-4.3,pi-saturation \
  --mixed 0,1,2,4 --mixed-driver human --mixed-controller protocol,follower-stopper-4.3,pi-saturation \
  --out out/compare-human
# Watch it: the law and stochastic humans (human-noisy) on the same ring from the same uniform
# start, SUMO's floating-car data kept for `syncroad replay out/watch/protocol` in sumo-gui,
# and both animated side by side on one clock and one colour scale (the README's picture).
./target/release/syncroad compare scenarios/sugiyama-human-noisy.json --baselines protocol,human-noisy \
  --fcd --no-plots --out out/watch
./target/release/syncroad animate out/watch/protocol out/watch/human-noisy --speedup 15 --size 280 \
  --out out/sugiyama-law-and-noisy-humans.gif
# Mixed rings among stochastic humans (human-noisy) over 20 seeds: a sweep of penetrations
# 0–50 % for the law and both dampers, resumable, into out/noisy-penetration/results.parquet
# with one plot per metric (mean and 95 % interval over seeds, which the humans' noise makes
# wider than zero); then the table, read in one line of pandas.
./target/release/syncroad sweep sweeps/noisy-penetration.json --out out/noisy-penetration
.venv/bin/python - <<'PY'
import pandas
df = pandas.read_parquet("out/noisy-penetration/results.parquet")
df["controller"] = df["run"].str.replace(r"-?mixed-[0-9.]+$", "", regex=True).replace("", "all human")
g = df.groupby(["controller", "penetration"])
m = g[["congestion.speed_std_mps", "sumo.fuel_g_per_km", "congestion.stopped_fraction"]]
half = 2.093 * m.std() / g.size().pow(0.5).values[:, None]   # t(0.975, 19): 20 seeds
print("mean over 20 seeds (± half-width of the 95 % interval):")
print((m.mean().round(3).astype(str) + " ± " + half.round(3).astype(str)).to_string(), flush=True)
print("unsafe runs (collisions, overlaps, teleports or emergency braking):")
print(df[df["safe"] == False].groupby(["controller", "penetration"]).size().to_string(), flush=True)
# pyarrow can abort at interpreter shutdown after the work is done (apache/arrow#34314).
import os
os._exit(0)
PY
