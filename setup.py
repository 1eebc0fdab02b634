"""The packages of the wheel (everything else is in pyproject.toml).

The code packages are found in the source tree, not listed: a list kept by hand left ``vfit_engine.textile``
out of the wheel. pyproject.toml's ``packages.find`` cannot do it, since it names a package after its
directory and ``cli/`` installs as ``vfit_cli`` (``package-dir`` there). The data packages are the folders
whose files pyproject.toml's ``package-data`` declares.
"""
from setuptools import find_packages, setup

CODE = (find_packages(include=["vfit_engine", "vfit_engine.*"])
        + ["vfit_cli"] + [f"vfit_cli.{name}" for name in find_packages(where="cli")])
DATA = ["vfit_engine.data", "vfit_engine.data.garments"]

setup(packages=CODE + DATA)
