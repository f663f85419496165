"""The package's version (``jointid.__version__``) and the digest of its code, in a module of its own: a lower
layer that names them (the provenance of an uninstalled checkout, a record kept for a later run) imports this,
not the package with its API."""

import hashlib
from functools import lru_cache
from pathlib import Path

__version__ = "0.1.0"


@lru_cache(maxsize=1)
def code_digest() -> str:
    """Digest of the package's Python sources: a record made by other code is not taken (the diagnosis's
    memo, :mod:`jointid.diagnosis.memo`; the dataset checks, :mod:`jointid.data.checked`)."""
    root = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        h.update(str(path.relative_to(root)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()
