"""Evolution over arrays: the building blocks of every algorithm here, and the algorithms on them.

Populations are plain arrays: X ``(n, d)``, F ``(n, m)``, G ``(n, k)``, CV ``(n,)`` (sum of positive G).
Blocks are pure functions (``sorting``, ``selection``, ``variation``, ``duplicates``, ``spea2``, ``weights``);
algorithms (``nsga2``, ``imtcmo``, ``moead_cmt``, ...) are pymoo ``Algorithm`` subclasses
(``base.ArrayAlgorithm``) that build pymoo Populations only at the API boundary, so
``pymoo.optimize.minimize``, terminations and callbacks work unchanged.
"""
