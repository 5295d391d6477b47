"""Which packages the distribution holds; everything else is in pyproject.toml.

The top-level ``cad/`` (bundled link scripts) and ``data/`` (model files, seed Table 1)
folders are shipped inside the packages, as ``linkfea/_cad`` and ``vjm/_data``, so that an
installed package finds them with importlib.resources (``linkfea.runtime.resources``) while the
source tree keeps its layout.  The package list is computed so that new subpackages of
``src/`` are picked up without editing this file.
"""
from setuptools import find_namespace_packages, find_packages, setup

# data/realdata/ (measured data sets, a few MB) stays in the source tree: the benchmarks read it there.
DATA = ["vjm._data"] + [f"vjm._data.{p}" for p in find_namespace_packages("data", exclude=["realdata", "realdata.*"])]

setup(
    packages=find_packages("src") + ["linkfea._cad"] + DATA,
    package_dir={"": "src", "linkfea._cad": "cad", "vjm._data": "data"},
)
