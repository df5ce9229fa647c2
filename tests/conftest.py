"""Shared helpers for the test suite."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

DATA = Path(__file__).parent / "data"
ROBOTS = Path(__file__).resolve().parents[1] / "robots"


@pytest.fixture
def data_dir() -> Path:
    return DATA


def random_configuration(model: pin.Model, rng: np.random.Generator, scale: float = 1.0) -> np.ndarray:
    """A configuration a random tangent step away from neutral (valid on every joint group)."""
    return pin.integrate(model, pin.neutral(model), scale * rng.standard_normal(model.nv))
