"""What analysis may know about the plant of a run: its kind and, for scoring only, the
true parameters its binding offers (``[true_parameters]`` of ``scenarios/plants/*.toml``),
in SI under contract names. Never an FMU variable name: that is the binding's business."""
from __future__ import annotations


def _binding(result, plant: str):
    system = getattr(result, "system", None)
    return None if system is None else system.bindings.get(plant)


def plant_kind(result, plant: str, default: str | None = None) -> str:
    """``"ball_screw"`` or ``"linear_stage"``: from the run's binding (or its summary)."""
    b = _binding(result, plant)
    if b is not None:
        return b.kind
    kind = ((getattr(result, "summary", None) or {}).get("plants") or {}).get(plant, {}).get("kind")
    if kind is None and default is None:
        raise ValueError(f"plant '{plant}' has no binding in this run (scenario key [fmus.{plant}] plant = "
                         "\"scenarios/plants/<name>.toml\"): its kind is unknown")
    return kind or default


def true_parameters(result, plant: str) -> dict[str, float]:
    """True plant parameters for scoring (contract names, SI); ``{}`` when the binding
    offers none or the run is not at hand (a result read back from disk)."""
    b = _binding(result, plant)
    if b is None:
        return {}
    slave = result.system.slaves[plant]
    return b.true_values(slave.model, slave.parameters)
