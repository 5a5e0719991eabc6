"""Packages whose public names are imported when first used (PEP 562): importing one module of
the library (`strokekit.run.spec`, the options) does not load the whole library, its kernels
and backends; the command line's --help imports its option declarations alone."""

from __future__ import annotations

import importlib
import sys


def exports(package: str, names: dict[str, str]):
    """The module `__getattr__` of `package`: each of `names` ({public name: the module that
    defines it}) imported from its module when first asked for, then kept on the package."""

    def __getattr__(name: str):
        module = names.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        setattr(sys.modules[package], name, value)
        return value

    return __getattr__
