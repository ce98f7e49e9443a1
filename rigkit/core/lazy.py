"""A package's public names, imported on first use.

A package that re-exports its modules' names (``from rigkit.rig import RigProfile``)
would otherwise import every module behind them whenever any one of its modules is
imported: reading a frame loaded the whole pipeline and SciPy's optimisers with it
(~0.6 s before the first byte was decoded, issue 38). With :func:`exports` as the
package's module-level ``__getattr__`` (PEP 562), a name's module is imported when the
name is first asked for, and a module of the package imports only what it imports.
"""

from __future__ import annotations

import importlib
import sys
import threading
from collections.abc import Callable, Mapping
from typing import Any


def exports(package: str, homes: Mapping[str, str]) -> Callable[[str], Any]:
    """The ``__getattr__`` of ``package`` giving each public name (key of ``homes``)
    from its module (the value, relative to the package)."""

    def attribute(name: str) -> Any:
        home = homes.get(name)
        if home is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f"{package}.{home}"), name)

    return attribute


def function(module: str, name: str) -> Callable[..., Any]:
    """``module.name``, a function, imported when it is first called: a module that may
    need a heavy library's function (SciPy's optimisers, ~0.5 s to import) does not
    make everything that imports it wait for that library."""

    def call(*args: Any, **kwargs: Any) -> Any:
        return getattr(load(module), name)(*args, **kwargs)

    call.__name__ = call.__qualname__ = name
    call.__doc__ = f"{module}.{name}, imported on first call."
    return call


def preload(*modules: str) -> None:
    """Import ``modules`` in a thread of their own while this one does other work (reads
    and decodes frames, which leave the interpreter free): a whole ``rigkit depth`` waits
    ~0.5 s less for SciPy on two cores. For libraries outside rigkit that import nothing
    of it, so that the two threads never wait for each other's half-imported modules;
    where a module is already imported, nothing is started. A failed import is left for
    the thread that uses the module to raise, where it is reported."""
    missing = [name for name in modules if name not in sys.modules]
    if missing:
        thread = threading.Thread(target=_import_all, args=(missing,), name="rigkit-preload")
        with _lock:  # listed once started; it leaves the list under the same lock
            thread.start()
            _preloading.append(thread)


def load(module: str) -> Any:
    """``importlib.import_module(module)`` once any :func:`preload` under way has ended.
    Two threads importing one library's modules at once can deadlock where its modules
    import each other (Python then raises in one of them); rigkit's own imports of a
    library that may be preloading go through here."""
    with _lock:
        running = list(_preloading)
    for thread in running:
        thread.join()
    return importlib.import_module(module)


_lock = threading.Lock()
_preloading: list[threading.Thread] = []
"""The preload threads started, until they end."""


def _import_all(modules: list[str]) -> None:
    for name in modules:
        try:
            importlib.import_module(name)
        except Exception:  # raised again, and reported, where the module is used
            break
    with _lock:
        _preloading.remove(threading.current_thread())
