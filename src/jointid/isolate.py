"""A memory-heavy step in a process of its own: ``call(func, *args)``.

The function runs in a fresh Python (``python -m jointid.isolate IN OUT``) on its pickled arguments, and
its pickled answer comes back.  When the child exits, all of its memory is returned to the system, so the
caller's largest process is not the sum of its own data and the step's.  Used where a step needs much more
memory than the job holds otherwise (the refined meshes of the diagnosis's mesh error,
:mod:`jointid.diagnosis.mesh_error`).  The child limits its linear-algebra libraries to one thread, as
every job of the workflow does (:func:`jointid.threads.limit_threads`), and runs the same code on the same
inputs, so its answer is the one the caller would have computed.

An exception in the child is raised again in the caller (the same type where it can be pickled); a
child killed by a signal (e.g. the system's out-of-memory killer) is a :class:`jointid.errors.ModelError`
that says so.
"""

from __future__ import annotations

import importlib
import os
import pickle
import subprocess
import sys
import tempfile
import traceback

__all__ = ["call"]


def call(func, *args, what: str = "the step", **kwargs):
    """``func(*args, **kwargs)`` computed in a child process (module doc).  ``func`` must be a module-level
    function; ``what`` names the step in an error."""
    from jointid.errors import ModelError

    with tempfile.TemporaryDirectory(prefix="jointid-isolate-") as tmp:
        inp, out = os.path.join(tmp, "in.pkl"), os.path.join(tmp, "out.pkl")
        with open(inp, "wb") as fh:
            pickle.dump((func.__module__, func.__qualname__, args, kwargs), fh, protocol=pickle.HIGHEST_PROTOCOL)
        env = dict(os.environ)
        here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # the folder holding jointid
        env["PYTHONPATH"] = os.pathsep.join(filter(None, (here, env.get("PYTHONPATH"))))
        rc = subprocess.run([sys.executable, "-m", "jointid.isolate", inp, out], env=env).returncode
        if rc < 0:
            raise ModelError(f"{what}: its process was killed by signal {-rc}"
                              + (" (out of memory?)" if -rc == 9 else "") + ": run again with more free memory")
        if not os.path.exists(out):
            raise ModelError(f"{what}: its process ended with exit code {rc} and no answer (its output is above)")
        with open(out, "rb") as fh:
            ok, value = pickle.load(fh)
    if ok:
        return value
    if isinstance(value, BaseException):
        raise value
    raise ModelError(f"{what} failed in its process:\n{value}")


def _main(inp: str, out: str) -> int:
    from jointid.threads import limit_threads

    limit_threads(1)
    try:
        with open(inp, "rb") as fh:
            module, name, args, kwargs = pickle.load(fh)
        func = importlib.import_module(module)
        for part in name.split("."):
            func = getattr(func, part)
        result = (True, func(*args, **kwargs))
    except Exception as exc:  # noqa: BLE001 - handed to the caller, which raises it
        result = (False, exc)
        try:
            pickle.loads(pickle.dumps(exc))
        except Exception:  # noqa: BLE001 - an exception that cannot be pickled: its text
            result = (False, "".join(traceback.format_exception(exc)))
    with open(out + ".part", "wb") as fh:
        pickle.dump(result, fh, protocol=pickle.HIGHEST_PROTOCOL)
    os.replace(out + ".part", out)
    return 0


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1], sys.argv[2]))
