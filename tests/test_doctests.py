"""The examples in the public docstrings run and print what they say."""

import doctest

import pytest

import data_tools.synthetic
import nrsfm.pipeline
import nrsfm.settings


@pytest.mark.parametrize("module", [nrsfm.pipeline, nrsfm.settings, data_tools.synthetic])
def test_docstring_examples(module):
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0 and result.attempted > 0, result
