"""Shared test set-up: fast mode for tutorials and scripts, a private cache folder per session."""

import os

import pytest

os.environ.setdefault("DEXART_LITE_FAST", "1")


@pytest.fixture(scope="session", autouse=True)
def _private_cache(tmp_path_factory):
    """Generated files (the composed robot URDF) go to a fresh folder, as on a new machine."""
    os.environ["DEXART_LITE_CACHE"] = str(tmp_path_factory.mktemp("dexart_cache"))
