"""How a syncroad worker loads SUMO into its embedded interpreter.

The worker needs libsumo's compiled module only: it starts, steps and closes SUMO and reads and
commands the vehicles through that module's functions (and calls the C++ functions it exports
directly). `import libsumo` would also run the package's `__init__`, which builds TraCI's
Python wrappers (it imports traci, sumolib and numpy) and reads installed versions from the
package metadata: half of the 0.34 s that `import libsumo` takes (`python -X importtime`). So the
compiled module is loaded on its own, under the name the package gives it
(`libsumo._libsumo`): a later `import libsumo` (a user's controller reading traffic lights)
finds it loaded and the package wraps this very module, so both see one simulation.

`sumo_home()` sets the environment as `import sumo` does (the eclipse-sumo wheel, imported
first until now: `SUMO_HOME` and `PROJ_LIB`/`PROJ_DATA` where unset), without importing it.
"""

import importlib.machinery
import importlib.util
import os
import sys


# What was found once (a worker runs many jobs; every job asks again).
_found = {}


def _package(name):
    """The spec and folder of the installed package `name`, without importing it."""
    spec = importlib.util.find_spec(name)
    if spec is None or not spec.submodule_search_locations:
        raise ImportError(f"No module named '{name}'", name=name)
    return spec, list(spec.submodule_search_locations)[0]


def sumo_home():
    """The eclipse-sumo wheel's SUMO_HOME, put into the environment where unset."""
    if "sumo_home" in _found:
        return _found["sumo_home"]
    _, home = _package("sumo")
    _found["sumo_home"] = home
    if "SUMO_HOME" not in os.environ:
        os.environ["SUMO_HOME"] = home
    if not os.environ.get("PROJ_LIB") and not os.environ.get("PROJ_DATA"):
        os.environ["PROJ_LIB"] = os.environ["PROJ_DATA"] = os.path.join(home, "data", "proj")
    return home


def libsumo():
    """libsumo's compiled module (the one loaded already, if any) and the package's file."""
    loaded = sys.modules.get("libsumo._libsumo")
    if loaded is not None and "origin" in _found:
        return loaded, _found["origin"]
    spec, folder = _package("libsumo")
    _found["origin"] = spec.origin
    if loaded is not None:
        return loaded, spec.origin
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        path = os.path.join(folder, "_libsumo" + suffix)
        if os.path.isfile(path):
            loader = importlib.machinery.ExtensionFileLoader("libsumo._libsumo", path)
            module_spec = importlib.util.spec_from_file_location("libsumo._libsumo", path, loader=loader)
            module = importlib.util.module_from_spec(module_spec)
            loader.exec_module(module)
            sys.modules["libsumo._libsumo"] = module
            return module, spec.origin
    raise ImportError(f"libsumo's compiled module _libsumo is not in {folder}", name="libsumo")
