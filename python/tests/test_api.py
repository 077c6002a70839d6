"""The API's results against the CLI's on the same input, and against what the files say
when read independently."""

import csv
import json
import re
import shutil
import subprocess

import pyarrow as pa
import pytest

import syncroad
from conftest import REPO, cli, plain, read_json


def csv_rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.mark.parametrize(
    "scenario, backend, command",
    [
        ("scenarios/sugiyama-ring.json", None, "run"),  # SUMO, in a worker process
        ("scenarios/ring-theorem1.json", None, "run"),  # native
        ("scenarios/sugiyama-ring.json", "native", "simulate"),
    ],
)
def test_run_equals_the_cli(tmp_path, scenario, backend, command):
    r = syncroad.run(scenario, backend=backend, out=tmp_path / "api")
    p = cli(command, scenario, "--out", tmp_path / "cli")
    assert p.returncode == r.exit_code, p.stderr
    mine, theirs = read_json(tmp_path / "api/metrics.json"), read_json(tmp_path / "cli/metrics.json")
    assert mine == theirs
    assert r.metrics == theirs
    assert (tmp_path / "api/trajectories.csv").read_bytes() == (tmp_path / "cli/trajectories.csv").read_bytes()
    assert r.verdict == theirs["sync"]["verdict"]
    # The summary the CLI prints, captured.
    assert plain(r.summary, tmp_path / "api") == plain(p.stdout, tmp_path / "cli")
    rows = csv_rows(tmp_path / "cli/trajectories.csv")
    t = r.trajectories
    assert isinstance(t, pa.Table)
    assert t.num_rows == len(rows)
    assert t.column("speed_mps").to_pylist()[-1] == pytest.approx(float(rows[-1]["speed_mps"]), rel=0, abs=0)
    want_backend = backend or read_json(REPO / scenario)["backend"]
    assert r.metrics.backend == want_backend
    if want_backend == "sumo":
        assert r.metrics.sumo_version.startswith("SUMO 1.28.0")


def test_the_record_agrees_with_the_trajectories_it_was_computed_from(tmp_path):
    # Independent of the record: the spread max_i v_i − min_i v_i at the last sample, computed
    # here from the rows, is the record's final spread.
    r = syncroad.run("scenarios/ring-theorem1.json", out=tmp_path)
    df = r.trajectories.to_pandas()
    last = df[df.time_s == df.time_s.max()]
    assert len(last) == r.metrics.vehicles == 22
    spread = last.speed_mps.max() - last.speed_mps.min()
    assert r.metrics.sync.final_spread_mps == pytest.approx(spread, rel=1e-12)
    assert r.verdict == "synchronized"
    assert spread <= r.metrics.sync.thresholds["tolerance_mps"]


def test_plots_are_the_runs_and_copy_into_a_folder(tmp_path):
    r = syncroad.run("scenarios/ring-theorem1.json", out=tmp_path / "run")
    found = r.plots()
    assert set(found) == {f"{n}.{e}" for n in ("time_space", "speeds", "spread") for e in ("png", "svg")}
    copies = r.plots(tmp_path / "figures")
    png = copies["time_space.png"].read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and png == found["time_space.png"].read_bytes()
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine/time_space.png").write_text("not ours")
    with pytest.raises(FileExistsError):
        r.plots(tmp_path / "mine")
    assert (tmp_path / "mine/time_space.png").read_text() == "not ours"
    bare = syncroad.run("scenarios/ring-theorem1.json", out=tmp_path / "bare", plots=False)
    with pytest.raises(FileNotFoundError):
        bare.plots()
    # pdf=True is --pdf: each plot also as a PDF.
    paper = syncroad.run("scenarios/ring-theorem1.json", out=tmp_path / "paper", pdf=True)
    pdfs = {k: v for k, v in paper.plots().items() if k.endswith(".pdf")}
    assert set(pdfs) == {"time_space.pdf", "speeds.pdf", "spread.pdf"}
    assert all(p.read_bytes()[:5] == b"%PDF-" for p in pdfs.values())


def test_check_and_stability_are_the_clis_json():
    for scenario in ("scenarios/sugiyama-ring.json", "scenarios/ring-unstable.json"):
        rep = syncroad.check(scenario)
        assert rep == json.loads(cli("check", scenario, "--json").stdout)
        st = syncroad.stability(scenario)
        assert st == json.loads(cli("stability", scenario, "--json").stdout)
    # Theorem 1 certifies the Sugiyama ring; the exact analysis agrees.
    assert syncroad.check("scenarios/sugiyama-ring.json").certified is True
    assert syncroad.stability("scenarios/sugiyama-ring.json").verdict == "synchronizes"
    assert syncroad.stability("scenarios/ring-unstable.json").verdict != "synchronizes"


def test_compare_gives_one_row_per_run_as_each_run_recorded_it(tmp_path):
    # Baselines as the CLI flag writes them (the guide gives a list).
    df = syncroad.compare("scenarios/sugiyama-ring.json", baselines="protocol,krauss", out=tmp_path, jobs=2, plots=False)
    assert list(df.index) == ["protocol", "krauss"]
    doc = read_json(tmp_path / "compare.json")
    assert df.attrs["compare"] == doc
    for name in df.index:
        rec = read_json(f"{df.loc[name, 'out']}/metrics.json")
        assert rec["run"] == name
        assert df.loc[name, "sync.verdict"] == rec["sync"]["verdict"]
        assert df.loc[name, "congestion.speed_std_mps"] == rec["congestion"]["speed_std_mps"]
    # The protocol run is the scenario's own run: the same verdict and spread as `syncroad run`.
    solo = syncroad.run("scenarios/sugiyama-ring.json", out=tmp_path / "solo", plots=False)
    assert df.loc["protocol", "sync.verdict"] == solo.verdict == "synchronized"
    assert df.loc["protocol", "sync.final_spread_mps"] == solo.metrics.sync.final_spread_mps


def small_sweep(base):
    return {
        "name": "small",
        "base": base,
        "backend": "native",
        "axes": [
            {"field": "scale.gain", "values": [0.5, 2.0]},
            {"field": "scale.delay", "values": [0.5, 8.0]},
        ],
    }


def test_sweep_equals_the_clis_table_and_resumes(tmp_path):
    import pandas as pd

    spec = small_sweep(str(REPO / "scenarios/ring-theorem1.json"))
    df = syncroad.sweep(spec, out=tmp_path / "api", jobs=2)
    (tmp_path / "spec.json").write_text(json.dumps(spec))
    cli("sweep", tmp_path / "spec.json", "--out", tmp_path / "cli", "--jobs", "2", check_code=0)
    theirs = pd.read_parquet(tmp_path / "cli/results.parquet")
    pd.testing.assert_frame_equal(df, theirs, check_like=False)
    assert len(df) == 4
    assert df.attrs["exit_code"] == 0
    # A relative base resolves against base_dir; a second call resumes: nothing runs again.
    again = syncroad.sweep(small_sweep("scenarios/ring-theorem1.json"), out=tmp_path / "api", base_dir=REPO)
    pd.testing.assert_frame_equal(again, df)
    # Scaling every delay by 8 pushes the ring past its exact stability boundary.
    by = df.set_index(["scale.gain", "scale.delay"])["sync.verdict"]
    assert by[(0.5, 0.5)] == "synchronized"
    assert by[(2.0, 8.0)] != "synchronized"


def test_safety_and_fail_on_are_the_clis_flags(tmp_path):
    import pandas as pd

    # safety= is --safety: the same record as the CLI's run with the flag.
    r = syncroad.run("scenarios/ring-theorem1.json", out=tmp_path / "api", safety="filter", plots=False)
    cli("simulate", "scenarios/ring-theorem1.json", "--safety", "filter", "--no-plots", "--out", tmp_path / "cli", check_code=0)
    assert r.metrics == read_json(tmp_path / "cli/metrics.json")
    assert r.metrics.safety_layer.mode == "filter"
    e = syncroad.run("scenarios/sugiyama-ring.json", out=tmp_path / "fuel", emissions=True, plots=False)
    cli("run", "scenarios/sugiyama-ring.json", "--emissions", "--no-plots", "--out", tmp_path / "fuel-cli", check_code=0)
    assert e.metrics.sumo.fuel_g_per_km == read_json(tmp_path / "fuel-cli/metrics.json")["sumo"]["fuel_g_per_km"] > 0
    with pytest.raises(syncroad.ScenarioError, match="safety = 'gipps': use"):
        syncroad.run("scenarios/ring-theorem1.json", out=tmp_path / "bad", safety="gipps")
    # fail_on= is --fail-on: exit code 1 exactly when a row is not synchronized, the table
    # the same as without it.
    spec = small_sweep(str(REPO / "scenarios/ring-theorem1.json"))
    df = syncroad.sweep(spec, out=tmp_path / "sweep", fail_on="not-synchronized", plots=False)
    assert df.attrs["exit_code"] == (1 if (df["sync.verdict"] == "not_synchronized").any() else 0)
    plain_df = syncroad.sweep(spec, out=tmp_path / "sweep", plots=False)
    assert plain_df.attrs["exit_code"] == 0
    pd.testing.assert_frame_equal(df, plain_df)


def test_a_copied_run_folder_opens_as_a_run(tmp_path):
    r = syncroad.run("scenarios/ring-theorem1.json", out=tmp_path / "a", plots=False)
    shutil.copytree(tmp_path / "a", tmp_path / "b")
    again = syncroad.Run(tmp_path / "b")
    assert again.metrics == r.metrics and again.verdict == r.verdict
    with pytest.raises(FileNotFoundError):
        syncroad.Run(tmp_path)


def test_the_trajectory_of_your_own_vehicles_names_them(tmp_path):
    """``sumo.controlled`` on the shipped ring: three vehicles of the user's file, written out of
    order, are the trajectory's vehicles 0, 1, 2 in ring order, and each starts at the speed
    its own line of the file gives."""
    sc = json.loads((REPO / "scenarios/sugiyama-ring.json").read_text())
    shutil.copy(REPO / "sumo-nets/sugiyama-ring.net.xml", tmp_path / "ring.net.xml")
    depart = {"mine.b": ("arc1", 30.0, 6.0), "mine.a": ("arc0", 10.0, 7.0), "mine.c": ("arc2", 20.0, 5.0)}
    lines = [
        '<routes>',
        '    <vType id="mine" length="5" sigma="0"/>',
        '    <route id="all" edges="arc0 arc1 arc2 arc3 arc0 arc1 arc2 arc3 arc0 arc1 arc2 arc3"/>',
        '    <route id="from1" edges="arc1 arc2 arc3 arc0"/>',
        '    <route id="from2" edges="arc2 arc3 arc0 arc1"/>',
    ]
    route = {"arc0": "all", "arc1": "from1", "arc2": "from2"}
    for vid, (edge, pos, v) in depart.items():
        lines.append(
            f'    <vehicle id="{vid}" type="mine" route="{route[edge]}" depart="0" departLane="0" '
            f'departPos="{pos}" departSpeed="{v}"/>'
        )
    lines.append("</routes>")
    (tmp_path / "mine.rou.xml").write_text("\n".join(lines) + "\n")
    sc.update(vehicles=3, horizon_s=60)
    sc["model"]["delay_s"] = 0.5
    sc["sumo"] = {"net": "ring.net.xml", "routes": ["mine.rou.xml"], "controlled": {"id": r"mine\.[a-z]"}}
    run = syncroad.run(syncroad.Scenario.from_dict(sc, base_dir=tmp_path), out=tmp_path / "run", plots=False)
    assert run.complete
    # Ring order from the start of arc0: a (arc0), then back around: c (arc2), b (arc1).
    assert run.vehicle_ids == ["mine.a", "mine.c", "mine.b"]
    df = run.trajectories.to_pandas()
    df["id"] = df["vehicle"].map(dict(enumerate(run.vehicle_ids)))
    first = df[df["time_s"] == df["time_s"].min()].set_index("id")["speed_mps"]
    for vid, (_, _, v) in depart.items():
        assert first[vid] == pytest.approx(v, abs=1e-9), vid
    ours = syncroad.run("scenarios/ring-theorem1.json", out=tmp_path / "ours", plots=False)
    assert ours.vehicle_ids is None


def test_an_open_road_of_inflows_runs_from_python(tmp_path):
    """The guide's on-ramp (``examples/open-road``, built here by the project's netconvert) with
    no vehicles of its own: ``syncroad.run`` gives its record, whose ``guests`` block counts the
    FollowerStoppers among the highway's inflow as SUMO's floating-car data does, and whose
    verdict says there is none to give; the trajectory has no rows."""
    for f in ["onramp.nod.xml", "onramp.edg.xml", "onramp.json"]:
        shutil.copy(REPO / "examples/open-road" / f, tmp_path / f)
    netconvert = REPO / ".venv/lib/python3.11/site-packages/sumo/bin/netconvert"
    subprocess.run(
        [str(netconvert), "--node-files", "onramp.nod.xml", "--edge-files", "onramp.edg.xml",
         "--no-turnarounds", "true", "-o", "onramp.net.xml"],
        cwd=tmp_path, check=True, capture_output=True,
    )
    sc = json.loads((tmp_path / "onramp.json").read_text())
    sc.update(horizon_s=120)
    sc["sumo"]["fcd"] = True
    run = syncroad.run(syncroad.Scenario.from_dict(sc, base_dir=tmp_path), out=tmp_path / "run", plots=False)
    assert run.complete
    m = run.metrics
    assert m["sync"]["verdict"] == "inconclusive"
    assert "no vehicles of its own" in m["sync"]["verdict_reason"]
    g = m["guests"]
    assert g["laws"] == ["inflow0: follower-stopper-25"]
    fcd = (tmp_path / "run" / "sumo" / "fcd.xml").read_text()
    ids = set(re.findall(r'<vehicle id="([^"]+)"[^>]*type="syncroad_guest0"', fcd))
    assert g["entered"] == len(ids) > 0
    assert m["all_vehicles"]["collisions"] == 0
    assert run.trajectories.to_pandas().empty


def test_a_linear_law_written_in_python_is_certified_analysed_and_run(tmp_path):
    # Three identical agents y''' + y'' + 2y' = u all-to-all with gain 0.5: each mode is
    # s³ + s² + 2s + 1.5c, so Routh gives c* = 2/1.5 at ω* = √2; no file of the user's.
    law = {
        "name": "py-linear", "backend": "native", "seed": 1, "step_s": 0.01, "horizon_s": 60,
        "vehicles": 3, "road": {"type": "ring", "length_m": 300},
        "model": {"type": "linear", "graph": {"type": "all_to_all", "gain": 0.5},
                  "agents": {"eta": [1], "rho": [2, 1, 1]}},
        "initial": {"speed_mps": 10.0, "perturbation": {"speed_mps": 0.5}},
    }
    sc = syncroad.Scenario.from_dict(law)
    rep = syncroad.check(sc)
    # Re W(iω) = −1/((2 − ω²)² + ω²): smallest denominator 7/4 at ω² = 3/2, so α = 4/7.
    assert abs(rep.agents[0]["ifp_index"] - 4 / 7) < 1e-12
    assert rep.theorem1.holds == (0.5 * 2 * 4 / 7 < 0.5)
    st = syncroad.stability(sc)
    assert abs(st.network.critical.critical_gain_scale - 2 / 1.5) < 1e-9
    assert abs(st.network.critical.crossing_frequency_rad_s - 2 ** 0.5) < 1e-9
    assert st.verdict == "synchronizes"
    r = syncroad.run(sc, out=tmp_path / "run")
    assert r.verdict == "synchronized"
    # The agent's index on its own, and a delayed integrator's: α = kτ.
    assert abs(syncroad.ifp([1], [2, 1, 1]).alpha - 4 / 7) < 1e-12
    assert syncroad.ifp([2], [4], delay_s=0.6).alpha == pytest.approx(0.3, rel=1e-15)
    with pytest.raises(syncroad.SyncroadError, match="Hurwitz"):
        syncroad.ifp([1], [1, -1, 1])
