"""The report formatters: the one percentage formatter in each of the formats the reports
print, numbers, aligned plain-text tables and Markdown tables."""

import pytest

from validation.output.formatting import aligned, markdown_table, number, percent


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


def test_number():
    assert number(1.23456, ".3f") == "1.235"
    assert number(12.5, ".3g", "%") == "12.5%"
    assert number(None, ".3f") == "-"
    assert number(0.0, ".1f", missing="") == "0.0"


def test_aligned_pads_each_column_to_its_widest_cell():
    lines = aligned([("a", "bb", "c"), ("ccc", "d", 7)])
    assert lines == ["a    bb  c", "ccc  d   7"]
    assert aligned([]) == []


def test_markdown_table():
    assert markdown_table(("x", "y"), [("1", "2")]) == ["| x | y |", "|---|---|", "| 1 | 2 |"]
    assert markdown_table(("x",)) == ["| x |", "|---|"]
