"""`check --junit`: well-formed XML whatever the files contain, and counts that a real consumer
(junitparser) agrees with, including files with nothing to check (skipped)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from typer.testing import CliRunner

from lagrange_cli.check import FileReport, Result, to_json, to_junit
from lagrange_cli.cli import app
from lagrange_cli.errors import Span

from .conftest import ROOT

junitparser = pytest.importorskip("junitparser")

# Characters XML 1.0 cannot hold (NUL, ESC, form feed, lone surrogates, U+FFFE/U+FFFF), DEL and
# a C1 control, markup characters, line breaks and a terminal escape sequence.
HOSTILE = "a\x00b\x1b[2J\x07\x0c\x7f\x85\ud800\udfff\ufffe\uffff\"'<>&]]>\n\r\tz \u2028 \U0001f600"


def parse(text: str) -> junitparser.JUnitXml:
    ET.fromstring(text.encode("utf-8"))  # well-formed, and encodable as the header says
    return junitparser.JUnitXml.fromstring(text)


def assert_counts_agree(xml: junitparser.JUnitXml) -> None:
    """Each suite's attributes, and the totals on <testsuites>, are the counts of its cases."""
    totals = [0, 0, 0, 0]
    for suite in xml:
        stated = (suite.tests, suite.failures, suite.errors, suite.skipped)
        suite.update_statistics()
        assert stated == (suite.tests, suite.failures, suite.errors, suite.skipped), suite.name
        counted = (len(list(suite)), *(sum(1 for case in suite if any(isinstance(r, kind) for r in case.result)) for kind in (junitparser.Failure, junitparser.Error, junitparser.Skipped)))
        assert stated == counted, suite.name
        totals = [a + b for a, b in zip(totals, stated, strict=True)]
    assert [xml.tests, xml.failures, xml.errors, xml.skipped] == totals


def test_hostile_text_gives_well_formed_xml() -> None:
    span = Span(f"dir{HOSTILE}/f.yaml", 3, 4)
    reports = [
        FileReport(f"p{HOSTILE}", (Result(f"entry{HOSTILE}", False, f"detail{HOSTILE}", span), Result("momenta.x", True, "", span))),
        FileReport(f"q{HOSTILE}", error=f"{HOSTILE}\nsecond line"),
        FileReport(f"\x1b{HOSTILE}"),
    ]
    text = to_junit(reports)
    xml = parse(text)
    suites = list(xml)
    assert len(suites) == 3
    for suite in suites:
        for ch in ("\x00", "\x1b", "\x07", "\x0c", "\x7f", "\x85", "\ufffe", "\uffff"):
            assert ch not in suite.name
    cases = list(suites[0])
    assert cases[0].name.startswith("entry") and "<>&" in cases[0].name and cases[0].name.endswith("\U0001f600")
    assert "U+001B[2J" in cases[0].result[0].message and "U+D800" in cases[0].result[0].message
    assert "\x1b" not in text and "\ud800" not in text
    assert_counts_agree(xml)


@pytest.mark.parametrize(
    "kinds",
    [("pass",), ("fail",), ("error",), ("skip",), ("pass", "fail", "error", "skip"), ("skip", "skip", "pass"), ("fail", "fail", "error")],
)
def test_counts_agree_with_junitparser(kinds: tuple[str, ...]) -> None:
    span = Span("f.yaml", 1, 1)
    made = {
        "pass": lambda i: FileReport(f"{i}.yaml", (Result("equations", True, "", span), Result("momenta.x", True, "", span))),
        "fail": lambda i: FileReport(f"{i}.yaml", (Result("equations", False, "wrong", span), Result("momenta.x", True, "", span), Result("conserved.x", False, "no", span))),
        "error": lambda i: FileReport(f"{i}.yaml", error=f"{i}.yaml:1:1: error: bad"),
        "skip": lambda i: FileReport(f"{i}.yaml"),
    }
    reports = [made[kind](i) for i, kind in enumerate(kinds)]
    xml = parse(to_junit(reports))
    assert_counts_agree(xml)
    by_kind = dict(zip(kinds, xml, strict=True))
    if "skip" in by_kind:
        suite = by_kind["skip"]
        assert (suite.tests, suite.skipped, suite.failures, suite.errors) == (1, 1, 0, 0)
        assert all(case.is_skipped for case in suite)
    if "fail" in by_kind:
        assert by_kind["fail"].failures == 2
    assert xml.skipped == kinds.count("skip")
    assert [r.status for r in reports] == list(kinds)


def test_file_without_expect_is_skipped_not_passed(tmp_path: Path) -> None:
    plain = tmp_path / "plain.yaml"
    plain.write_text("title: no answers\ncoordinates: [x]\nparameters: [m, k]\nkinetic: m*x_dot**2/2\npotential: k*x**2/2\n")
    junit = tmp_path / "report.xml"
    result = CliRunner().invoke(app, ["check", str(plain), str(ROOT / "systems" / "kepler.yaml"), "--junit", str(junit)])
    assert result.exit_code == 0, result.output
    xml = parse(junit.read_text(encoding="utf-8"))
    assert_counts_agree(xml)
    skipped, checked = list(xml)
    assert (skipped.tests, skipped.skipped) == (1, 1) and checked.skipped == 0 and checked.tests >= 1
    report = FileReport(str(plain))
    assert report.status == "skip"
    assert '"skip": 1' in to_json([report])
