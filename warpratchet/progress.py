"""The one progress bar: a tqdm bar on stderr over the steps of a run or the points of a sweep.

:class:`ProgressBar` is an :class:`~warpratchet.ensemble.Observer` (``begin / after_chunk /
end``) for :meth:`Ensemble.run <warpratchet.ensemble.Ensemble.run>` and anything built on it
(``run``, ``resume``, ``sumrule``), and a counter (:meth:`~ProgressBar.open`,
:meth:`~ProgressBar.advance`, :meth:`~ProgressBar.close`) for sweeps, which count points.
It lives below the CLI because the API draws it too (``run_sweep(progress=True)``).

The command line's bar is drawn only on a terminal (``disable=None`` in tqdm), so logs, pipes and
``--json`` output stay clean; ``disable=True`` (``--quiet``) turns it off everywhere. The API's
bar (``Ensemble.run(progress=True)``, ``notebook=True`` here) is ``tqdm.auto``'s: a widget in
Jupyter (where stderr is no terminal, yet the user asked for a bar), text elsewhere.
"""

from __future__ import annotations

import sys
from typing import Any

__all__ = ["ProgressBar"]


class ProgressBar:
    """A tqdm bar on stderr; an ensemble observer over steps, or a counter over sweep points.

    Parameters
    ----------
    description : str
        Label on the left of the bar (``"steps"``, ``"points"``).
    disable : bool
        Never draw (``--quiet``). Otherwise the bar is drawn only when stderr is a terminal.
    unit : str
        What one count is (``"step"``, ``"point"``).
    notebook : bool
        Asked for from the API: ``tqdm.auto`` (a Jupyter widget where one is available), drawn
        whether or not stderr is a terminal.
    """

    def __init__(
        self, description: str = "steps", disable: bool = False, unit: str = "step", notebook: bool = False
    ) -> None:
        self.description = description
        self.disable = disable
        self.unit = unit
        self.notebook = notebook
        self._bar: Any = None
        self._first_step = 0

    # -- a counter ---------------------------------------------------------------------------------
    def open(self, total: int, initial: int = 0) -> None:
        """Start a bar at ``initial`` of ``total``."""
        if self.disable:  # nothing to draw: not even tqdm's import
            return
        if self.notebook:
            from tqdm.auto import tqdm
        else:
            from tqdm import tqdm

        self._bar = tqdm(
            total=total,
            initial=initial,
            desc=self.description,
            unit=self.unit,
            unit_scale=True,
            file=sys.stderr,
            # None: tqdm draws only on a terminal, so logs and pipes stay clean.
            disable=True if self.disable else (False if self.notebook else None),
            dynamic_ncols=True,
        )

    @property
    def drawing(self) -> bool:
        """Whether a bar is open and visible (the postfix costs a little: skip it otherwise)."""
        return self._bar is not None and not self._bar.disable

    def advance(self, to: int | None = None, postfix: str | None = None) -> None:
        """Move the bar to ``to`` (default: one further), with an optional text on its right."""
        if not self.drawing:
            return
        self._bar.update((self._bar.n + 1 if to is None else to) - self._bar.n)
        if postfix is not None:
            self._bar.set_postfix_str(postfix, refresh=False)

    def close(self) -> None:
        """Close the bar (idempotent)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    # -- an ensemble observer ----------------------------------------------------------------------
    def begin(self, ensemble, target_step: int) -> None:
        self._first_step = ensemble.step
        self.open(target_step, ensemble.step)

    def after_chunk(self, ensemble, seconds: float) -> None:
        if self.drawing:
            elapsed = max(self._bar.format_dict["elapsed"], 1e-9)
            rate = ensemble.points * (ensemble.step - self._first_step) / elapsed
            self.advance(ensemble.step, f"{rate / 1e6:.0f} M point-steps/s")

    def end(self, ensemble) -> None:
        self.close()
