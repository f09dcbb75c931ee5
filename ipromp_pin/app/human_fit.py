"""What a command does with its model's body-model self-check (:mod:`ipromp_pin.human.fit`).

A model trained on demos with a tracked skeleton records whether the demonstrated robot stayed clear
of the recorded body, and the registration correction fitted to them (``ipromp-pin train``; the
model file's ``human_fit``). ``run``, ``plan`` and ``replay``:

* judge every tracked body of that model's sessions through the corrected registration
  (:func:`model_registration`, :func:`~ipromp_pin.human.fit.registered`);
* warn (one line) when the body model, calibrated, still does not fit the demonstrations, or refuse
  with ``--strict-human`` (:class:`HumanModelMisfit`, exit status 3).

A model without the record (no skeleton in its training demos, a model file of format version 6 or
older, a model trained by the command itself) is "not measured": no warning, no correction.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from ..exceptions import IPrompPinError

if TYPE_CHECKING:  # imported when used: the command line's error handling imports this module
    from ..human.fit import HumanFit, Registration
    from ..promp import IProMP


class HumanModelMisfit(IPrompPinError):
    """``--strict-human``: the model's body model is known not to fit its demonstrations (exit 3)."""


def model_fit(model: IProMP, source: str = "model") -> HumanFit | None:
    """The model's self-check (None: not measured)."""
    from ..human.fit import HumanFit

    record = getattr(model, "human_fit_", None)
    return None if record is None else HumanFit.from_json(dict(record), source)


def model_registration(model: IProMP, source: str = "model") -> Registration | None:
    """The registration correction the model's sessions use (None: none)."""
    from ..human.fit import registration_of

    return registration_of(getattr(model, "human_fit_", None), source)


def misfit_line(fit: HumanFit | None, source: str) -> str | None:
    """One line when ``fit`` says the body model does not fit (None when it fits or is unmeasured)."""
    if fit is None or fit.fits:
        return None
    measures = fit.calibrated or fit.recorded
    problems = "; ".join(measures.problems())
    return (
        f"{source}: the human model does not fit its training demonstrations ({problems}): the human "
        f"checks judge a body that cannot be where it is drawn (docs/human_model.md)"
    )


def check_human_fit(model: IProMP, source: str, strict: bool, warn: Callable[[str], None]) -> str | None:
    """Warn (``warn``) or, when ``strict``, refuse when the model's body model is known not to fit;
    the warning line (None: no warning).

    Raises:
        HumanModelMisfit: ``strict`` and the body model does not fit.
    """
    line = misfit_line(model_fit(model, source), source)
    if line is None:
        return None
    if strict:
        raise HumanModelMisfit(f"{line}; refused (--strict-human)")
    warn(line)
    return line
