"""Fixtures the engine's stages share."""

from __future__ import annotations

import pytest
import synthetic


@pytest.fixture(scope="module")
def corpus():
    """The synthetic corpus (tests/synthetic.py): studies and bedrooms with known regularities."""
    return synthetic.corpus()
