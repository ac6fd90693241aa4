"""ncbot: a data-efficient deep-learning stack for a social humanoid robot that plays Noughts & Crosses.

The packages are the repository's top-level folders (``envs/``, ``modules/``, ``vision/``, ``speech/``, ``logs/``,
``robot_sim/``, ``pipelines/``, ``fileio/``); installed, they are ``ncbot.envs``, ``ncbot.modules``, ... (pyproject's
package-dir), so no other distribution's ``envs`` or ``logs`` is shadowed. Run from a source checkout that is not
installed (``PYTHONPATH=CHECKOUT python -m ncbot ...``), this file adds the checkout to the package's search path so
the same names resolve to those folders.
"""
from __future__ import annotations

from pathlib import Path

_here = Path(__file__).resolve().parent
_checkout = _here.parent
if not (_here / "envs").is_dir() and (_checkout / "pyproject.toml").is_file() and (_checkout / "envs" / "__init__.py").is_file():
    __path__.append(str(_checkout))  # noqa: F821 (a package's __path__)


def _register_with_gymnasium() -> None:
    """Make ``gymnasium.make("ncbot/NoughtsCrosses-v0")`` work after ``import ncbot``, whichever is imported first.

    ``ncbot.envs`` registers the id when it is imported; importing gymnasium costs ~0.4 s, too much for every
    ``ncbot`` command, so gymnasium is not imported here: when it is loaded already, ``ncbot.envs`` registers now,
    else a one-shot import hook registers right after the first ``import gymnasium`` completes.
    """
    import importlib
    import sys

    if "gymnasium" in sys.modules:
        importlib.import_module("ncbot.envs")
        return
    import importlib.abc
    import importlib.util

    class RegisterAfterGymnasium(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):  # noqa: ANN001 - the finder protocol
            if name != "gymnasium":
                return None
            sys.meta_path.remove(self)  # one shot; and the real finders answer below
            spec = importlib.util.find_spec(name)
            if spec is None or spec.loader is None or not hasattr(spec.loader, "exec_module"):
                return spec
            loader = spec.loader

            class Loader(importlib.abc.Loader):
                def create_module(self, spec):  # noqa: ANN001
                    return loader.create_module(spec)

                def exec_module(self, module):  # noqa: ANN001
                    module.__spec__.loader = module.__loader__ = loader  # gymnasium sees its own loader
                    loader.exec_module(module)
                    importlib.import_module("ncbot.envs")._register_gym()

            spec.loader = Loader()
            return spec

    sys.meta_path.insert(0, RegisterAfterGymnasium())


_register_with_gymnasium()
