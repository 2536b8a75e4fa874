"""What a score or plot function needs from a run, known before the run starts.

A score function is ``function(result, **settings) -> dict`` and a plot function
``function(result, out_dir, **settings)``. Two things are checked when the scenario
loads, so that a typo or a plant without a needed role fails before any FMU runs:

* the settings bind to the function's signature (an unknown or missing setting names
  the scenario file and the ``scores[i].settings`` key);
* the signals it reads, declared with :func:`needs` as templates over its settings
  (``"{plant}.i_meas"``), exist -- for a plant role, that the plant's binding binds
  it -- and they are recorded whatever ``[record] signals`` says. A template ending in
  ``?`` is optional: read when it exists, skipped otherwise.
"""
from __future__ import annotations

import inspect


def needs(*templates: str):
    """Declare the signals a score/plot function reads, as templates over its settings."""
    def mark(fn):
        fn.needs = tuple(templates)
        return fn
    return mark


def bind_settings(fn, settings: dict, positional: int) -> inspect.BoundArguments:
    """``settings`` bound to ``fn`` after ``positional`` leading arguments (TypeError if not)."""
    bound = inspect.signature(fn).bind(*([None] * positional), **settings)
    bound.apply_defaults()
    return bound


def needed_signals(fn, bound: inspect.BoundArguments) -> list[tuple[str, bool]]:
    """``(signal, required)`` for each template of :func:`needs` with the settings filled in."""
    args = {k: v for k, v in bound.arguments.items() if isinstance(v, str)}
    out = []
    for template in getattr(fn, "needs", ()):
        optional = template.endswith("?")
        try:
            sig = template.rstrip("?").format(**args)
        except (KeyError, IndexError):
            continue                       # a template over a setting that is not a name
        out.append((sig, not optional))
    return out
