"""Write tests/fixtures/ab3dmot_eval/python_sums.json: float sums as CPython 3.11, 3.12 and 3.13 compute them.

Run with the default interpreter (any); it runs pyenv's 3.11 / 3.12 / 3.13 on the same cases (pure
Python, no package needed) and stores each one's ``sum`` (repr-exact JSON floats), so the tests of
``dfrmot_jax.metrics.samota.sums`` check both behaviours on every interpreter, not only the running one.
"""

import glob
import json
import random
import subprocess
import sys
from pathlib import Path

OUT = Path(__file__).resolve().parent.parent / "tests" / "fixtures" / "ab3dmot_eval" / "python_sums.json"


def cases(seed: int = 7) -> list[list[float]]:
    """Repeated values (the evaluator's re-averages), mixed signs and magnitudes, near-equal values, scores."""
    rnd = random.Random(seed)
    out = []
    for i in range(240):
        n = rnd.choice([1, 2, 3, 7, 40, 111, 265])
        kind = i % 6
        if kind == 0:
            v = [rnd.uniform(-5, 15)] * n
        elif kind == 1:
            v = [rnd.uniform(-50, 50) for _ in range(n)]
        elif kind == 2:
            v = [rnd.choice([1e-10, 3.3, 1e8, -7.25, 0.1, 1e16, -1e16]) for _ in range(n)]
        elif kind == 3:
            x = rnd.uniform(0, 20)
            v = [x * (1 + rnd.choice([0.0, 1e-16, -1e-16])) for _ in range(n)]
        elif kind == 4:
            v = [round(rnd.uniform(-3, 12), 4) for _ in range(n)]
        else:
            v = [rnd.uniform(-1, 1) * 10 ** rnd.randint(-20, 20) for _ in range(n)]
        out.append(v)
    # last: a case where the compensated sum is not math.fsum's correctly rounded one
    out.append([63050394783186944.0, -3.0, 63050394783186944.0, 1e100, -1.0, -3.0000000000000002e100])
    return out


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--sums":
        print(json.dumps([sum(c) for c in json.loads(sys.stdin.read())]))
        sys.exit(0)
    cs = cases()
    doc = {"cases": cs, "sums": {}}
    for minor in ("3.11", "3.12", "3.13"):
        exe = sorted(glob.glob(str(Path.home() / f".pyenv/versions/{minor}.*/bin/python")))
        if not exe:
            sys.exit(f"no pyenv CPython {minor}")
        run = subprocess.run([exe[-1], __file__, "--sums"], input=json.dumps(cs), capture_output=True, text=True,
                             check=True)
        version = subprocess.run([exe[-1], "-c", "import platform; print(platform.python_version())"],
                                 capture_output=True, text=True, check=True).stdout.strip()
        doc["sums"][version] = json.loads(run.stdout)
    OUT.write_text(json.dumps(doc))
    print(f"wrote {OUT} ({OUT.stat().st_size} bytes): {', '.join(doc['sums'])}")
