"""CLM Studio's headless library, one package per layer (imports point down only):
cli -> study -> formats -> optimize -> analysis -> kinematics. Never imports viser, plotly or ``studio``.
See docs/architecture.md.
"""

from core.kinematics.kernel_cache import configure as _configure_kernel_cache

_configure_kernel_cache()
