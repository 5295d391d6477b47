"""Shared pytest fixtures."""
import os
import sys

import pytest

# Structured test meshes live next to the tests (tests/meshes.py).
sys.path.insert(0, os.path.dirname(__file__))

from linkfea.materials import get_material


@pytest.fixture(scope="session")
def steel():
    """Steel, E = 210 GPa, nu = 0.3 (N, mm, MPa)."""
    return get_material("steel")
