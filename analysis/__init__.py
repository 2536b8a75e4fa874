"""Offline analysis: scoring, identification and calibration fits, campaigns and figures.

Nothing here runs inside the 10 kHz loop. The dependency points one way: ``analysis``
may import ``controllers`` and ``cosim``; ``controllers`` never imports ``analysis``
(``tests/test_layering.py`` keeps it so).
"""
