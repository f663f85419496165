"""A step in a process of its own: ``call(func, *args)``, or a :class:`Worker` started ahead of it.

The function runs in a fresh Python (``python -m jointid.isolate [MODULE...]``) on its pickled arguments,
and its pickled answer comes back.  Two uses:

* **memory**: when the child exits, all of its memory is returned to the system, so the caller's largest
  process is not the sum of its own data and the step's (the refined meshes of the diagnosis's mesh error,
  :mod:`jointid.diagnosis.mesh_error`: :func:`call`);
* **the second core**: a :class:`Worker` started at the beginning of a job imports what its step needs
  while the job computes, and makes the step while the job goes on (the diagnosis page's figures,
  :func:`jointid.stages.diagnosis.run_diagnosis`).  Where the job has the machine to itself (the loop of
  docs/effects.md) that time is off its wall time; where every core is busy it costs one process start.

The child limits its linear-algebra libraries to one thread, as
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

__all__ = ["Worker", "call"]


class Worker:
    """A child process started ahead of its step (module doc).  It imports the modules ``preload`` (an entry
    ``"module:function"`` also calls that function, a warm-up) while the caller works on, computes the one
    call :meth:`submit` hands it while the caller goes on, and
    :meth:`result` returns the answer.  ``what`` names the step in an error.  Use it as a context manager
    (or call :meth:`close`): a child not asked is ended."""

    def __init__(self, *preload: str, what: str = "the step", env: dict | None = None):
        self.what = what
        self._tmp = tempfile.TemporaryDirectory(prefix="jointid-isolate-")
        self._inp = os.path.join(self._tmp.name, "in.pkl")
        self._out = os.path.join(self._tmp.name, "out.pkl")
        full = dict(os.environ)
        here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # the folder holding jointid
        full["PYTHONPATH"] = os.pathsep.join(filter(None, (here, full.get("PYTHONPATH"))))
        full.update(env or {})
        self._proc = subprocess.Popen([sys.executable, "-m", "jointid.isolate", *preload],
                                      stdin=subprocess.PIPE, env=full)
        self._sent = False

    def submit(self, func, *args, **kwargs) -> None:
        """Hand the child ``func(*args, **kwargs)`` (``func``: a module-level function) and return at once."""
        with open(self._inp, "wb") as fh:
            pickle.dump((func.__module__, func.__qualname__, args, kwargs), fh, protocol=pickle.HIGHEST_PROTOCOL)
        try:
            self._proc.stdin.write(f"{self._inp}\n{self._out}\n".encode())
            self._proc.stdin.close()
        except OSError:  # the child has ended: result() says how
            pass
        self._sent = True

    @property
    def asked(self) -> bool:
        """Whether :meth:`submit` handed the child its call (:meth:`result` would otherwise wait for nothing)."""
        return self._sent

    def result(self):
        """The answer of the submitted call (waits for it); the child's exception is raised again here."""
        from jointid.errors import ModelError

        rc = self._proc.wait()
        try:
            if rc < 0:
                raise ModelError(f"{self.what}: its process was killed by signal {-rc}"
                                 + (" (out of memory?)" if -rc == 9 else "") + ": run again with more free memory")
            if not os.path.exists(self._out):
                raise ModelError(f"{self.what}: its process ended with exit code {rc} and no answer (its output is above)")
            with open(self._out, "rb") as fh:
                ok, value = pickle.load(fh)
        finally:
            self.close()
        if ok:
            return value
        if isinstance(value, BaseException):
            raise value
        raise ModelError(f"{self.what} failed in its process:\n{value}")

    def close(self) -> None:
        """End the child if it still runs, and remove its files."""
        if self._proc.poll() is None:
            if not self._sent:
                try:
                    self._proc.stdin.close()  # end of input: the child exits without a call
                except OSError:
                    pass
            try:
                self._proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.wait()
        self._tmp.cleanup()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def call(func, *args, what: str = "the step", **kwargs):
    """``func(*args, **kwargs)`` computed in a child process (module doc).  ``func`` must be a module-level
    function; ``what`` names the step in an error."""
    with Worker(what=what) as worker:
        worker.submit(func, *args, **kwargs)
        return worker.result()


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


def _serve(preload: list[str]) -> int:
    """``python -m jointid.isolate MODULE[:FUNCTION]...``: import the modules (and call each function named,
    without arguments: a warm-up, e.g. a first figure drawn), then read the input and output paths of one
    call from stdin (none: exit) and make it."""
    for entry in preload:
        module, _, func = entry.partition(":")
        mod = importlib.import_module(module)
        if func:
            getattr(mod, func)()
    lines = sys.stdin.read().split("\n")
    if len(lines) < 2 or not lines[0]:
        return 0
    return _main(lines[0], lines[1])


if __name__ == "__main__":
    sys.exit(_serve(sys.argv[1:]))
