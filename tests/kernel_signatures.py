"""Fresh-interpreter checks that a warm-up compiles (or loads) every numba kernel signature a later computation
uses: the warm-up, then the computation, each followed by a count of the compiled signatures of every ``ancf``
kernel (``signatures()``, defined in the script's header); a kernel whose count grew was compiled by the
computation, i.e. a run would wait for the compiler there."""

import json
import os
import subprocess
import sys
import textwrap

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

HEADER = textwrap.dedent("""
    import json, sys
    import numpy as np
    from numba.core.registry import CPUDispatcher

    def signatures():
        out = {}
        for name, mod in list(sys.modules.items()):
            if name.split(".")[0] != "ancf":
                continue
            for attr, obj in list(vars(mod).items()):
                if isinstance(obj, CPUDispatcher):
                    out[f"{name}.{attr}"] = len(obj.signatures)
        return out
""")


def run_fresh(body: str, *args: str) -> dict:
    """Run ``HEADER + body`` (dedented) in a new interpreter from the repository root with ``args``; the JSON object
    on its last output line."""
    run = subprocess.run([sys.executable, "-c", HEADER + textwrap.dedent(body), *args], cwd=ROOT,
                         env={**os.environ, "PYTHONPATH": ROOT}, capture_output=True, text=True, timeout=600,
                         check=False)
    assert run.returncode == 0, run.stderr[-2000:]
    return json.loads(run.stdout.strip().splitlines()[-1])


def grown(before: dict, after: dict) -> dict:
    """The kernels with more signatures ``after`` than ``before``: name → (before, after)."""
    return {k: (before.get(k, 0), n) for k, n in after.items() if n > before.get(k, 0)}
