"""How much the database's random draw matters: databases trained alike with several seeds
(the bundled database's training command with ``--seed N``; kept in ``--cache``, so a run
resumes), the whole flight suite flown with each, and a table row printed per seed.

    python studies/dove_database_seeds.py --seeds 1-8 [--cache seed_dbs] [--samples 10000]
        [--feathers rigid|modal] [--config FILE.toml] [--eval-args "--k 100"] [--quick]
        [--json out.json]

``--config`` flies the suite under a control configuration file (``[controller]`` and
``[path]`` tables; ``flapsim list config`` prints the defaults); ``--eval-args`` passes other
``flapsim eval`` options. Each database takes ~3.3 min to train and the suite ~2.5 min to fly
on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import shlex
import subprocess
import sys
from pathlib import Path

from flapsim import scenarios
from flapsim.core.io import write_json


def _seeds(text: str) -> list[int]:
    out = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


def _row(seed: int, result: dict) -> tuple[str, int]:
    S = {x["scenario"]: x for x in result["scenarios"] if x["family"] == "flight"}

    def st(name: str, ef: bool = False) -> str:
        x = S.get(name)
        if x is None:
            return "-"
        if x["status"] == "completed":
            return f"completed ({x['metrics']['Ef_per_wingbeat']:.3f})" if ef else "completed"
        return "lost"

    def pushes(newtons: float) -> list[str]:
        return [n[5:] for n in S if n.startswith("push-") and any(
            r["newtons"] == newtons and r["survived"] for r in S[n]["metrics"]["table"])]

    done = sum(x["status"] == "completed" for x in S.values())
    p8 = pushes(8.0)
    cells = [str(seed), st("figure8", True), st("figure8-rise3"), st("figure8-level", True),
             st("sinusoid"), st("forest"), st("wind-steady-2"), st("wind-gusts"), st("flock"),
             f"{len(pushes(6.0))} of 6", "all six" if len(p8) == 6 else (", ".join(p8) or "none"),
             f"{done} of {len(S)}"]
    return "| " + " | ".join(cells) + " |", done


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="1-8", help="seeds, e.g. 1-8 or 1,3,5 (default 1-8)")
    ap.add_argument("--samples", type=int, default=10000, help="samples per database (default 10000)")
    ap.add_argument("--cache", default="seed_dbs", help="folder of the databases and suite results")
    ap.add_argument("--config", default=None, help="control configuration file for the suite (TOML)")
    ap.add_argument("--eval-args", default="", help="more flapsim eval arguments, quoted")
    ap.add_argument("--quick", action="store_true", help="the suite's short variants (smoke run)")
    ap.add_argument("--json", default=None, help="write the table and every suite's results here")
    ap.add_argument("--feathers", choices=("rigid", "modal"), default="rigid",
                    help="the dove the databases are trained on and flown with")
    return ap


def main(argv: list[str] | None = None) -> None:
    ap = parser()
    a = ap.parse_args(argv)
    cache = Path(a.cache)
    cache.mkdir(exist_ok=True)
    flight = scenarios.names(family="flight", all_only=True)
    rows, results = [], {}
    for seed in _seeds(a.seeds):
        tag = "" if a.feathers == "rigid" else "modal_"
        db = cache / f"{tag}seed{seed}.db"
        if not db.exists():
            subprocess.run([sys.executable, "-m", "flapsim.cli.main", "train", "--samples", str(a.samples),
                            "--pre-pitch-deg", "10", "--pre-roll-deg", "10", "--seed", str(seed),
                            "--float32", "--feathers", a.feathers, "--out", str(db)], check=True)
        out = cache / f"{tag}suite_seed{seed}.json"
        cmd = [sys.executable, "-m", "flapsim.cli.main", "eval", "--scenario", ",".join(flight),
               "--db", str(db), "--feathers", a.feathers, "--json", str(out),
               *(["--config", a.config] if a.config else []), *shlex.split(a.eval_args)]
        if a.quick:
            cmd.append("--quick")
        subprocess.run(cmd)  # exits 1 when a run got lost: the table says which
        results[seed] = json.loads(out.read_text())
        row, done = _row(seed, results[seed])
        rows.append(row)
        print(row, flush=True)
    print("| seed | figure8 (Ef m) | rise3 | level (Ef m) | sinusoid | forest | wind 2 m/s | gusts | "
          "flock | 6 N pushes | 8 N pushes | completed |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | ---: |")
    print("\n".join(rows))
    if a.json:
        write_json(a.json, {"seeds": list(results), "rows": rows, "suites": results})


if __name__ == "__main__":
    main()
