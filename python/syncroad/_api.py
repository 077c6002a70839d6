"""The commands of the CLI as functions: each builds the command line the CLI would be given,
runs it in-process through the extension (the very code of the ``syncroad`` binary), and
reads back the files and reports it wrote."""

from __future__ import annotations

import contextlib
import json
import numbers
import os
import tempfile
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any, Dict, Iterable, Iterator, List, Mapping, Optional, Sequence, Set, Tuple, Union

from syncroad import _syncroad
from syncroad._errors import Interrupted, RunError, ScenarioError
from syncroad._run import METRICS_FILE, Record, Run
from syncroad._scenario import PathLike, ScenarioLike, as_scenario, write_spec

if TYPE_CHECKING:
    import pandas

#: The CLI's exit codes (README, "Exit codes").
SUCCESS, NOT_SYNCHRONIZED, BAD_INPUT, RUN_FAILED = 0, 1, 2, 3


def _flags(**options: Any) -> List[str]:
    """``--name value`` for every option given (``None``: not given; ``True``: a bare flag;
    a list: comma-separated)."""
    argv: List[str] = []
    for name, value in options.items():
        if value is None or value is False:
            continue
        flag = "--" + name.replace("_", "-")
        if value is True:
            argv.append(flag)
        elif isinstance(value, (list, tuple)):
            argv += [flag, ",".join(str(v) for v in value)]
        else:
            argv += [flag, str(value)]
    return argv


#: The numeric keyword arguments the commands take: (integer?, smallest valid, inclusive?).
_NUMBERS: Dict[str, Tuple[bool, float, bool]] = {
    "record_every": (True, 1, True),
    "jobs": (True, 1, True),
    "tolerance_mps": (False, 0.0, False),
    "window_s": (False, 0.0, False),
    "warmup_s": (False, 0.0, True),
    "timeout_s": (False, 0.0, False),
    "krauss_sigma": (False, 0.0, True),
}


def _check_numbers(**options: Any) -> None:
    """Raises :class:`ScenarioError` for a numeric keyword argument of the wrong type or out
    of range, in Python's terms, before anything runs (the CLI would answer with its usage
    text, in terms of its flags)."""
    for name, value in options.items():
        if value is None:
            continue
        integer, lowest, inclusive = _NUMBERS[name]
        kind = "an integer" if integer else "a number"
        # numbers.Real and Integral: NumPy's scalars too (a value taken from a DataFrame).
        wanted = numbers.Integral if integer else numbers.Real
        if isinstance(value, bool) or not isinstance(value, wanted):
            raise ScenarioError(f"{name} = {value!r}: must be {kind} (got {type(value).__name__})")
        x = float(value)
        ok = x >= lowest if inclusive else x > lowest
        if not ok or x != x or x in (float("inf"), float("-inf")):
            bound = f"≥ {lowest:g}" if inclusive else f"> {lowest:g}"
            raise ScenarioError(f"{name} = {value!r}: must be {kind} {bound} (or None for the default)")


def _safety(layer: Optional[str]) -> Optional[str]:
    """Checks ``safety=`` before anything runs: the CLI's ``--safety`` values."""
    if layer is None or layer in ("off", "sumo", "filter"):
        return layer
    raise ScenarioError(
        f"safety = {layer!r}: use \"off\" (the law's commands as they are), \"sumo\" (SUMO's safe "
        "speed, right of way and red lights) or \"filter\" (syncroad's Gipps safe-speed filter, "
        "on both backends)"
    )


def _listed(values: Any) -> Any:
    """A list for an iterable of values; a string (already comma-separated) or None as is."""
    if values is None or isinstance(values, str):
        return values
    return list(values)


def _execute(argv: Sequence[str], out: Optional[Path] = None, here: bool = False
             ) -> Tuple[int, Optional[str], str]:
    """Runs ``syncroad ARGV`` in-process; bad input raises :class:`ScenarioError`, Ctrl-C
    raises :class:`Interrupted` once the command has stopped and written its rows. ``here``:
    its SUMO run steps in this process (whose libsumo the caller has claimed)."""
    try:
        code, error, stdout = _syncroad.execute(["syncroad", *argv], True, here)
    except KeyboardInterrupt:
        run = None
        if out is not None and (out / METRICS_FILE).is_file():
            run = Run(out)
        raise Interrupted(out, run) from None
    if code == BAD_INPUT:
        raise ScenarioError(error or "bad input")
    if code >= 128:
        # A signal the host did not deliver as KeyboardInterrupt (SIGTERM to a worker pool).
        raise Interrupted(out)
    return code, error, stdout


#: Output folders a call of this process is writing or reading back. The CLI's folder lock
#: excludes other processes while the command runs; this set also covers the moment between
#: the command's end and the call reading its files, where another thread's call would clear
#: them.
_writing_now: Set[str] = set()
_writing_lock = threading.Lock()


@contextlib.contextmanager
def _writing(folder: Path, name: str = "out") -> Iterator[None]:
    """Holds ``folder`` for one call: a second call of this process on the same folder (another
    thread) raises :class:`ScenarioError` naming it, as the CLI refuses a second writer."""
    key = os.path.realpath(folder)
    with _writing_lock:
        if key in _writing_now:
            raise ScenarioError(
                f"{name} = {folder}: another call of this process (pid {os.getpid()}) is writing "
                f"this folder; wait for it to end, or give another {name}"
            )
        _writing_now.add(key)
    try:
        yield
    finally:
        with _writing_lock:
            _writing_now.discard(key)


def _out_dir(out: Optional[PathLike], prefix: str) -> Path:
    return Path(out) if out is not None else Path(tempfile.mkdtemp(prefix=f"syncroad-{prefix}-"))


def run(
    scenario: ScenarioLike,
    backend: Optional[str] = None,
    out: Optional[PathLike] = None,
    *,
    plots: bool = True,
    pdf: bool = False,
    tolerance_mps: Optional[float] = None,
    window_s: Optional[float] = None,
    record_every: Optional[int] = None,
    warmup_s: Optional[float] = None,
    timeout_s: Optional[float] = None,
    krauss_sigma: Optional[float] = None,
    progress: Optional[str] = None,
    controller: Any = None,
    safety: Optional[str] = None,
    emissions: bool = False,
    _here: bool = False,
) -> Run:
    """Runs a scenario as ``syncroad run`` (``backend="native"``: ``syncroad simulate``)
    and returns its :class:`Run`. ``out`` is the run's folder (default: a new temporary one);
    the files are the CLI's. SUMO runs go to a supervised worker process. ``progress`` is the
    CLI's ``--progress``: ``"auto"`` (the default: a line redrawn on a terminal's stderr),
    ``"lines"`` (plain lines on stderr, for logs) or ``"never"``. ``safety`` is the CLI's
    ``--safety``: ``"off"``, ``"sumo"`` or ``"filter"`` in place of the scenario's layer;
    ``emissions=True`` is ``--emissions`` (SUMO runs: fuel and CO2 in ``metrics.sumo``);
    ``pdf=True`` is ``--pdf`` (every plot also as a PDF with real text, for a paper).

    Raises :class:`ScenarioError` for bad input, :class:`RunError` when the run failed part-way
    (``err.run`` keeps the rows received), :class:`Interrupted` on Ctrl-C (rows kept).

    Ctrl-C reaches a run the way it reaches any Python code: through the interpreter's
    ``KeyboardInterrupt``. A process started with SIGINT ignored (``nohup``, or ``python … &``
    in a script, where the shell ignores SIGINT for background jobs) ignores it during a run
    too, as Python itself does. Code that wants Ctrl-C there restores the handler first:
    ``signal.signal(signal.SIGINT, signal.default_int_handler)``.

    ``controller`` drives the vehicles in place of the scenario's law: an object with a
    ``step(obs)`` method (its class defined in a .py file; the object is pickled and its
    ``step`` runs inside the SUMO worker, or in this process natively) or a ``controller``
    block (``{"python": "FILE.py:Class", "params": {...}}``). See the guide's "Your own
    controller"."""
    sc = as_scenario(scenario)
    if backend not in (None, "native", "sumo"):
        raise ScenarioError(f'backend = {backend!r}: must be "native" or "sumo" (or None: the scenario\'s)')
    _check_numbers(
        tolerance_mps=tolerance_mps,
        window_s=window_s,
        record_every=record_every,
        warmup_s=warmup_s,
        timeout_s=timeout_s,
        krauss_sigma=krauss_sigma,
    )
    if backend == "native" and krauss_sigma is not None:
        raise ScenarioError('krauss_sigma applies to SUMO runs only; backend = "native" runs syncroad\'s own simulator')
    folder = _out_dir(out, "run")
    if backend == "sumo":
        sc = sc.with_backend("sumo")
    if controller is not None:
        # Last: the scenario it makes owns the pickled state's temporary folder.
        sc = sc.with_controller(controller)
    # `run` runs the scenario's backend; `simulate` the native simulator whatever the
    # scenario says, which takes no time limit: a native run with one is a `run` of the
    # scenario made native.
    if backend == "native" and timeout_s is not None:
        sc = sc.with_backend("native")
        backend = None
    command = "simulate" if backend == "native" else "run"
    if backend == "native" and emissions:
        raise ScenarioError('emissions applies to SUMO runs only; backend = "native" runs syncroad\'s own simulator')
    sumo_flags = _flags(timeout_s=timeout_s, krauss_sigma=krauss_sigma, emissions=emissions)
    argv = [command, str(sc.path), "--out", str(folder), *sumo_flags]
    argv += _flags(
        tolerance_mps=tolerance_mps,
        window_s=window_s,
        record_every=record_every,
        warmup_s=warmup_s,
        no_plots=not plots,
        pdf=pdf,
        progress=progress,
        safety=_safety(safety),
    )
    with _writing(folder):
        code, error, summary = _execute(argv, folder, here=_here)
        if code == RUN_FAILED or error is not None:
            partial = Run(folder, code, summary) if (folder / METRICS_FILE).is_file() else None
            if error is None and partial is not None:
                error = partial.metrics.get("error")
            raise RunError(error or f"the run failed (exit {code}); see {folder}", folder, partial)
        done = Run(folder, code, summary)
        done.metrics  # read while the folder is this call's
        return done


def check(scenario: ScenarioLike) -> Record:
    """The paper's sufficient conditions and the gap certificate (``syncroad check --json``):
    ``report.certified``, each condition with its margin, ``report.gap_certificate``."""
    sc = as_scenario(scenario)
    _, error, text = _execute(["check", str(sc.path), "--json"])
    if error is not None:
        raise RunError(error)
    return Record(json.loads(text))


def stability(scenario: ScenarioLike, platoon_scaling: bool = False) -> Record:
    """Exact stability (``syncroad stability --json``): the verdict, its certificate, the
    rightmost roots and the critical scales; with ``platoon_scaling``, ``{"report": …,
    "platoon_scaling": …}``."""
    sc = as_scenario(scenario)
    _, error, text = _execute(["stability", str(sc.path), "--json", *_flags(platoon_scaling=platoon_scaling)])
    if error is not None:
        raise RunError(error)
    return Record(json.loads(text))


def ifp(eta: Sequence[float], rho: Sequence[float], delay_s: float = 0.0) -> Record:
    """The IFP index of one agent ``W(s) = η(s)/(s ρ(s)) · e^{−s·delay_s}`` (``syncroad ifp
    --json``; coefficients lowest degree first): ``alpha``, exact for a rational agent and
    for a delayed integrator, otherwise a rigorous upper bound with ``lower_bound`` beside it.
    Raises :class:`ScenarioError` naming the hypothesis of Lemma lem.linear-pass that fails."""
    _, error, text = _execute(["ifp", *_flags(eta=list(eta), rho=list(rho), delay_s=float(delay_s)), "--json"])
    if error is not None:
        raise RunError(error)
    return Record(json.loads(text))


def _run_folders(out: Path) -> Dict[str, Path]:
    """Each run folder under ``out`` by the run name its record gives."""
    folders = {}
    for sub in sorted(p for p in out.iterdir() if (p / METRICS_FILE).is_file()):
        folders[json.loads((sub / METRICS_FILE).read_text()).get("run")] = sub
    return folders


def compare(
    scenario: ScenarioLike,
    baselines: Optional[Union[str, Iterable[str]]] = None,
    mixed: Optional[Union[str, Iterable[int]]] = None,
    out: Optional[PathLike] = None,
    *,
    mixed_driver: Optional[str] = None,
    mixed_controller: Optional[Union[str, Iterable[str]]] = None,
    jobs: Optional[int] = None,
    warmup_s: Optional[float] = None,
    ssm: bool = False,
    record_every: Optional[int] = None,
    timeout_s: Optional[float] = None,
    plots: bool = True,
    pdf: bool = False,
    safety: Optional[str] = None,
    fail_on: Optional[Union[str, Iterable[str]]] = None,
) -> "pandas.DataFrame":
    """Runs ``syncroad compare`` (the scenario's law beside SUMO's drivers, the wave dampers
    and mixed rings, each in its own SUMO worker) and returns one row per run, indexed by run
    name: the flattened record (``congestion.speed_std_mps``, ``sumo.fuel_g_per_km``, …),
    ``error`` for a run that failed, and ``out``, the run's folder (``syncroad.Run(row.out)``).
    ``df.attrs["compare"]`` is the whole ``compare.json``. ``safety`` and ``fail_on`` are the
    CLI's ``--safety`` and ``--fail-on`` (``"unsafe"``, ``"not-synchronized"``,
    ``"inconclusive"``): ``df.attrs["exit_code"]`` is 1 when a run matched."""
    import pandas as pd

    sc = as_scenario(scenario)
    _check_numbers(jobs=jobs, warmup_s=warmup_s, record_every=record_every, timeout_s=timeout_s)
    folder = _out_dir(out, "compare")
    argv = ["compare", str(sc.path), "--out", str(folder)]
    argv += _flags(
        baselines=_listed(baselines),
        mixed=_listed(mixed),
        mixed_driver=mixed_driver,
        mixed_controller=_listed(mixed_controller),
        jobs=jobs,
        warmup_s=warmup_s,
        ssm=ssm,
        record_every=record_every,
        timeout_s=timeout_s,
        no_plots=not plots,
        pdf=pdf,
        safety=_safety(safety),
        fail_on=_listed(fail_on),
    )
    with _writing(folder):
        code, error, _ = _execute(argv, folder)
        doc_path = folder / "compare.json"
        if not doc_path.is_file():
            raise RunError(error or f"compare wrote no compare.json (exit {code})", folder)
        doc = json.loads(doc_path.read_text())
        folders = _run_folders(folder)
    rows = []
    for name, record in doc["runs"].items():
        row = pd.json_normalize(record).iloc[0].to_dict()
        row["run"] = name
        row["out"] = str(folders[name]) if name in folders else None
        rows.append(row)
    df = pd.DataFrame(rows).set_index("run")
    df.attrs["compare"] = doc
    df.attrs["exit_code"] = code
    return df


def sweep(
    spec: Union[PathLike, Mapping[str, Any]],
    out: PathLike,
    jobs: Optional[int] = None,
    *,
    base_dir: Optional[PathLike] = None,
    shard: Optional[str] = None,
    retry_failed: bool = False,
    keep_runs: bool = False,
    plots: bool = True,
    pdf: bool = False,
    safety: Optional[str] = None,
    fail_on: Optional[Union[str, Iterable[str]]] = None,
) -> "pandas.DataFrame":
    """Runs a sweep spec (a file, or a dict whose relative ``base`` resolves against
    ``base_dir``) as ``syncroad sweep SPEC --out OUT`` and returns ``results.parquet`` as a
    DataFrame, one row per point. Resumable as the CLI's: after Ctrl-C (:class:`Interrupted`)
    or a failed point, the same call runs only the points without a row (``retry_failed``:
    the failed ones too). ``df.attrs["exit_code"]`` is 3 when some point failed (its row says
    ``status == "failed"``), 1 when a point matched ``fail_on`` (the CLI's ``--fail-on``).
    ``safety`` is the CLI's ``--safety``."""
    import pandas as pd

    _check_numbers(jobs=jobs)
    folder = Path(out)
    with _writing(folder), tempfile.TemporaryDirectory(prefix="syncroad-spec-") as tmp:
        path = write_spec(tmp, spec, base_dir) if isinstance(spec, Mapping) else Path(spec)
        argv = ["sweep", str(path), "--out", str(folder)]
        argv += _flags(
            jobs=jobs,
            shard=shard,
            retry_failed=retry_failed,
            keep_runs=keep_runs,
            no_plots=not plots,
            pdf=pdf,
            safety=_safety(safety),
            fail_on=_listed(fail_on),
        )
        code, error, _ = _execute(argv, folder)
        table = folder / "results.parquet"
        if not table.is_file():
            raise RunError(error or f"the sweep wrote no results.parquet (exit {code})", folder)
        df = pd.read_parquet(table)
    df.attrs["exit_code"] = code
    if error is not None:
        df.attrs["error"] = error
    return df
