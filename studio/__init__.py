"""CLM Studio: a viser design studio for closed-chain legged mechanisms.

``studio`` imports ``core``, viser and plotly; ``core`` never imports ``studio``. Pure pieces
(session state, geometry, figures, metric rows) are importable and testable without a server
or a browser; ``studio.app`` wires them to viser.
"""
