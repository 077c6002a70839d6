"""Trains a policy for the automated vehicle of a registered ring (by default
``syncroad/RingStern-v0``: one automated vehicle among 21 ``human-noisy`` drivers on the 230 m
Sugiyama ring, from Stern et al.'s uniform start, under syncroad's safety filter) and writes it
as a controller's policy file.

The policy is ``examples/controllers/linear_policy.py``'s: ``x = tanh(w · o + b)`` from the
environment's ``local`` observation, four parameters. It is searched by CMA-ES (the ``cma``
package, N. Hansen's reference implementation; an evolution strategy is a policy-search
method of reinforcement learning, Salimans et al. 2017), each candidate scored by its mean
reward over an episode of the environment. CPU only, no neural-network library.

    pip install 'syncroad[train]'      # gymnasium, cma, matplotlib
    python examples/learning/train_ring.py --out out/train-ring
    python examples/learning/train_ring.py --out out/quick --generations 2 --population 4 --episode-steps 300

Writes to ``--out``: ``policy.json`` (the best mean of the last generation's search
distribution, the controller's file), ``learning_curve.csv`` (per generation: episodes so
far, environment steps so far, seconds, the best, mean and worst candidate's return, the
policy's return) and ``learning_curve.png`` when matplotlib is installed. The same seed gives
the same policy.
"""

import argparse
import csv
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "controllers"))
from linear_policy import LinearPolicy  # noqa: E402


def policy_of(params, env):
    """The controller's policy for parameters ``[w_v, w_gap, w_ahead, b]``."""
    return {"weights": [float(x) for x in params[:3]], "bias": float(params[3]),
            "speed_scale_mps": env.unwrapped.speed_scale_mps,
            "accel_mps2": env.unwrapped._ep.accel_mps2, "decel_mps2": env.unwrapped._ep.decel_mps2}


def episode_return(env, policy, seed, steps):
    """The mean reward of one episode (``steps`` steps at most) driven by ``policy``."""
    law = LinearPolicy(policy)
    obs, _ = env.reset(seed=seed)
    total, n = 0.0, 0
    for _ in range(steps):
        # The action from the observation the environment gives: the controller computes the
        # same float32 values from the run's and the same arithmetic on them.
        x = law.act(obs)
        obs, reward, terminated, truncated, _ = env.step(np.array([x], dtype=np.float64))
        total += reward
        n += 1
        if terminated or truncated:
            break
    return total / n


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True, help="folder for policy.json and the learning curve")
    ap.add_argument("--env", default="syncroad/RingStern-v0",
                    help="a registered one-vehicle ring (syncroad/RingStern-v0, syncroad/Ring-v0)")
    ap.add_argument("--generations", type=int, default=40)
    ap.add_argument("--population", type=int, default=8)
    ap.add_argument("--episode-steps", type=int, default=3000,
                    help="steps of each episode after the warm-up (Ring-v0's 3000 at most)")
    ap.add_argument("--sigma", type=float, default=0.5,
                    help="CMA-ES's initial step size, times each weight's scale")
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args(argv)

    import cma
    import gymnasium

    import syncroad.gym  # noqa: F401 - registers the rings

    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    env = gymnasium.make(a.env)
    # The observation's values span about 0.2 (speeds over 30 m/s) and 0.1 (gaps over the
    # ring's 230 m): the search starts with steps of the weights' useful sizes, not of 1.
    es = cma.CMAEvolutionStrategy([0.0, 0.0, 0.0, 0.0], a.sigma,
                                  {"popsize": a.population, "seed": a.seed, "verbose": -9,
                                   "CMA_stds": [30.0, 100.0, 30.0, 3.0]})
    rows, episodes, steps, start = [], 0, 0, time.perf_counter()
    try:
        for g in range(a.generations):
            xs = es.ask()
            # Every candidate of a generation meets the same humans (one seed a generation):
            # their returns differ by the policy alone.
            seed = a.seed * 1000 + g
            returns = [episode_return(env, policy_of(x, env), seed, a.episode_steps) for x in xs]
            es.tell(xs, [-r for r in returns])
            episodes += len(xs)
            steps += len(xs) * a.episode_steps
            mean = es.result.xfavorite
            row = {"generation": g + 1, "episodes": episodes, "env_steps": steps,
                   "seconds": round(time.perf_counter() - start, 1),
                   "best_return": max(returns), "mean_return": float(np.mean(returns)),
                   "worst_return": min(returns),
                   "policy_return": episode_return(env, policy_of(mean, env), seed, a.episode_steps)}
            rows.append(row)
            print(json.dumps(row), flush=True)
    finally:
        env.close()
    policy = policy_of(es.result.xfavorite, env)
    policy["trained"] = {"environment": a.env, "method": "CMA-ES (cma)",
                         "generations": a.generations, "population": a.population,
                         "episode_steps": a.episode_steps, "seed": a.seed,
                         "episodes": episodes, "seconds": rows[-1]["seconds"] if rows else 0.0}
    (out / "policy.json").write_text(json.dumps(policy, indent=2) + "\n")
    with open(out / "learning_curve.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    figure(rows, out / "learning_curve.png", a.env)
    print(f"wrote {out / 'policy.json'} and the learning curve ({episodes} episodes, "
          f"{rows[-1]['seconds']} s)")


def figure(rows, path, env_id):
    """The learning curve, when matplotlib is installed."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    eps = [r["episodes"] for r in rows]
    fig, ax = plt.subplots(figsize=(6.4, 3.6), dpi=150)
    ax.fill_between(eps, [r["worst_return"] for r in rows], [r["best_return"] for r in rows],
                    color="#56B4E9", alpha=0.35, label="candidates (worst to best)")
    ax.plot(eps, [r["policy_return"] for r in rows], color="#0072B2", lw=2,
            label="the search's mean policy")
    ax.set_xlabel("episodes")
    ax.set_ylabel("mean reward per step")
    ax.set_title(f"CMA-ES on {env_id} (desired-velocity reward)")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


if __name__ == "__main__":
    main()
