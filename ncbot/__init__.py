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
