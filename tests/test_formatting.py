"""The one percentage formatter every report uses, in each of the formats they print."""

import pytest

from validation.output.formatting import percent


@pytest.mark.parametrize(("args", "text"), [
    ((0.0123,), "+1.23 %"),
    ((-0.354, "+.2f", ""), "-35.40%"),          # the lattice and Gecit tables
    ((0.05, ".2g"), "5 %"),                      # plan, validate-plan
    ((0.1234, ".3g"), "12.3 %"),                 # regimes
    ((0.021, "+.0f"), "+2 %"),                   # figures against the paper
    ((None,), "-"),
    ((None, "+.2f", " ", ""), ""),               # the elastic-fem3d bench's empty cell
])
def test_percent(args, text):
    assert percent(*args) == text
