"""Ask one page to confirm an action that loses or risks something (a modal with the action and Cancel)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import viser


def confirm(client: viser.ClientHandle, title: str, text: str, action: str, on_yes: Callable[[], None]) -> None:
    """Show ``text`` in a modal on ``client``'s page; ``on_yes`` runs only if the designer presses ``action``.

    Cancel (or closing the page) does nothing. The modal is the page's own: other pages do not see it.
    """
    modal = client.gui.add_modal(title)
    with modal:
        client.gui.add_markdown(text)
        yes = client.gui.add_button(action, color="red")
        no = client.gui.add_button("Cancel")

    def on_yes_click(_: Any) -> None:
        modal.close()
        on_yes()

    yes.on_click(on_yes_click)
    no.on_click(lambda _: modal.close())
