"""The true event times the stack scores are taken against (analysis.detector_scoring.stack_transitions)."""
import numpy as np

from drillcosim.analysis.detector_scoring import stack_transitions


def _layers(spans, n):
    """Layer index at 1 kHz: ``spans`` = [(t_start [s], layer), ...] in order, up to n samples."""
    t = np.arange(n) * 1e-3
    layer = np.zeros(n)
    for t0, k in spans:
        layer[t >= t0] = k
    return t, layer


def test_a_bounce_off_the_lower_layer_face_is_no_exit():
    # cfrp 1.0-3.0 s, gap, ti from 4.0 s with a 12 ms bounce back into the gap at 4.050 s
    # (foreign2 hole 147's contact), exit at 9.0 s: the exit is the last time the tip leaves
    # the Ti, not the bounce 5 s earlier
    t, layer = _layers([(1.0, 1), (3.0, 0), (4.0, 2), (4.050, 0), (4.062, 2), (9.0, 0)], 10000)
    (entry, _), (if_start, if_end), (ex, _) = stack_transitions(t, layer, 2)
    assert abs(entry - 1.0) < 1e-3 and abs(if_start - 3.0) < 1e-3 and abs(if_end - 4.0) < 1e-3
    assert abs(ex - 9.0) < 1e-3


def test_a_layer_never_left_has_no_exit():
    t, layer = _layers([(1.0, 1), (3.0, 2)], 5000)
    assert np.isnan(stack_transitions(t, layer, 2)[-1][0])
