"""GUI panels of the studio. Each panel builds its controls once and has ``show(...)`` to
mirror the session state into them; user edits go through ``Studio.session`` and then
``Studio.refresh()``. Callbacks ignore programmatic updates (``event.client is None``)."""
