"""FMI 2.0 log callbacks that route each instance's messages to that instance.

fmpy formats the variadic FMI 2.0 log messages in a native proxy (fmpy.logging) that
keeps ONE process-wide pointer to the Python logger: every addLoggerProxy() call
replaces it. A logger per instance therefore sends every FMU's messages to the last
instance created, and crashes once that instance's callback is garbage-collected.
Here one eternal dispatcher is registered; it routes by componentEnvironment.
"""
from __future__ import annotations

import itertools
import weakref
from ctypes import byref

import fmpy

_LOG_TARGETS: dict = {}
_LOG_KEYS = itertools.count(1)


def _dispatch_log(env, instance_name, status, category, message):
    ref = _LOG_TARGETS.get(env or 0)
    target = ref() if ref is not None else None
    if target is not None:
        try:
            target._log_message(status, category, message)
        except Exception:
            pass


_DISPATCH = None


def fmi2_callbacks(target):
    """``fmi2CallbackFunctions`` whose log messages reach ``target._log_message(status,
    category, message)``, safe with any number of FMI 2.0 instances per process."""
    global _DISPATCH
    from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                           fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)
    from fmpy.logging import addLoggerProxy
    if _DISPATCH is None:
        _DISPATCH = fmi2CallbackLoggerTYPE(_dispatch_log)
    key = next(_LOG_KEYS)
    _LOG_TARGETS[key] = weakref.ref(target)
    cb = fmi2CallbackFunctions()
    cb.logger = _DISPATCH
    cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
    cb.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)
    cb.componentEnvironment = key
    addLoggerProxy(byref(cb))
    return cb
