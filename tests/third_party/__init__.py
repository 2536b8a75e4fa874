"""Plant and test FMUs made by tools other than this project's C build (issue #7).

Each module builds its FMU on demand into a directory given by the caller (tests use
pytest's tmp_path_factory) and returns the path of the .fmu file.
"""
