"""CLM Studio's headless library, one package per layer (imports point down only):
cli -> study -> formats -> optimize -> analysis -> kinematics. Never imports viser, plotly or ``studio``.
See docs/architecture.md.
"""

import hashlib as _hashlib
from pathlib import Path as _Path

from core.kinematics.kernel_cache import configure as _configure_kernel_cache

_configure_kernel_cache()


def _digest() -> str:
    """12 hex digits of SHA-256 over every ``core/**/*.py`` file's path and bytes, read as the package is imported:
    the code this process runs (a digest read later named files edited since; ``core.study.provenance``)."""
    root = _Path(__file__).resolve().parent
    h = _hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        h.update(str(path.relative_to(root)).encode("utf-8") + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()[:12]


CODE_DIGEST = _digest()
