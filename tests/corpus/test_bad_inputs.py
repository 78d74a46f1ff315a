"""Every named bad input of the corpus (tests/corpus/cases.py), over every command: refused in one line with
the right exit status, earlier outputs unchanged, nothing written, no hang (tests/corpus/runner.py)."""
import pytest

from tests.corpus.cases import all_cases
from tests.corpus.runner import run_case

CASES = all_cases()


def test_the_corpus_covers_every_command():
    from psvs.cli.main import COMMANDS
    covered = {c.argv[0] for c in CASES}
    assert len(CASES) >= 150
    assert set(COMMANDS) <= covered, f"commands without a bad input: {sorted(set(COMMANDS) - covered)}"


@pytest.mark.parametrize("case", [pytest.param(c, id=c.name, marks=[pytest.mark.slow] if c.slow else [])
                                  for c in CASES])
def test_refused_in_one_line(case, tmp_path, capfd, monkeypatch):
    run_case(case, tmp_path, capfd, monkeypatch)
