#!/usr/bin/env python3
"""Kill storm: runs killed at random instants (SIGKILL), and whether what each left is whole.

    .venv/bin/python scripts/kill-storm.py --trials 1000 --out results/kill-storm   # forked runs, 1 rank
    .venv/bin/python scripts/kill-storm.py --every-point --trials 40 --out results/kill-storm   # the test's
    .venv/bin/python scripts/kill-storm.py --trials 100 --ranks 2 --out results/kill-storm   # mpirun -n 2

Prints one line per trial with a loss (and every 50th), then the counts: trials, kill points killed,
where the kills landed (outside an append, inside one, inside its commit; forked runs only), results.h5
left, commits cut short, checkpoints checked, restarts, and trials with a loss. Exit status 1 if anything was lost. What is checked:
tests/kills.py; docs/checkpoints.md#the-kill-storm.
"""

import argparse
import pathlib
import sys

import petsc4py

petsc4py.init([])

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests"))  # kills.py: a test tool
from kills import storm, summary  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--trials", type=int, default=500, help="runs to kill (default 500)")
    parser.add_argument("--ranks", type=int, default=0, help="run each under mpirun -n RANKS (default: forked, "
                        "one rank)")
    parser.add_argument("--slow", type=float, default=0.0005, help="seconds added to each disk write of "
                        "results.h5 (forked runs; default 0.0005), so that kills land inside appends")
    parser.add_argument("--restarts", type=int, default=20, help="trials whose run is then restarted and "
                        "compared with the uninterrupted one (default 20)")
    parser.add_argument("--every-point", action="store_true", help="first kill a forked run just before the "
                        "first call of each of its kill points (tests/kills.py), then the random trials")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="results/kill-storm", help="working directory (default "
                        "results/kill-storm); a trial with a loss keeps its files there")
    args = parser.parse_args()

    def log(trial):
        if trial.lost or trial.index % 50 == 0:
            when = f"before {trial.point}" if trial.point else f"{trial.after:.3f} s in"
            print(f"trial {trial.index}: killed {when} ({trial.phase}); results.h5 "
                  f"{trial.steps} steps, {trial.fields} fields; {trial.checkpoints} checkpoints; commit cut "
                  f"short: {trial.torn}; lost: {'; '.join(trial.lost) or 'nothing'}", flush=True)

    trials = storm(args.out, args.trials, seed=args.seed, slow=args.slow if not args.ranks else 0.0,
                   restarts=args.restarts, ranks=args.ranks, log=log, every_point=args.every_point)
    counts = summary(trials)
    width = max(map(len, counts))
    for name, value in counts.items():
        print(f"{name:<{width}}  {value}")
    return 1 if counts["trials with a loss"] else 0


if __name__ == "__main__":
    sys.exit(main())
