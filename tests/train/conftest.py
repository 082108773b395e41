"""Fixtures of the training tests: a toy dataset made in well under a second."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def toy_data(tmp_path_factory):
    from spacemesh.train.toy import make_toy_dataset

    return make_toy_dataset(tmp_path_factory.mktemp("toy") / "data", count=30, seed=0)


from tests.export.conftest import toy_model  # noqa: E402, F401  (one toy model per session)
