"""make reproduce's steps: each names real presets, and the README's table of them is a report's, step for step."""

import shutil

from experiments.generated import README, markers
from experiments.reproduce import NOT_IN_REPORT, README_COMMAND, STEPS, readme_from_report, steps_table
from experiments.schemas import CONFIG_DIR
from experiments.steps import Section


def test_every_step_runs_presets_that_exist_and_says_what_it_writes():
    assert len({step.title for step in STEPS}) == len(STEPS)
    for step in STEPS:
        assert step.scale in ("default", "paper") and step.outputs
        for preset in step.presets:
            assert (CONFIG_DIR / "experiment" / f"{preset}.yaml").exists(), preset


def readme_rows_from(done, tmp_path) -> list[tuple[str, str]]:
    """The README's (step, minutes) rows after copying a report of ``done`` into it."""
    begin, end = markers("steps", "make reproduce")
    report = tmp_path / "report.md"
    report.write_text(f"# Reproduction report\n\n{begin}\n{steps_table(done)}\n{end}\n")
    readme = shutil.copy(README, tmp_path / "README.md")
    readme_from_report(report, readme)
    text = readme.read_text()
    block = text.split(markers("reproduce", README_COMMAND)[0], 1)[1].split(markers("reproduce", README_COMMAND)[1])[0]
    rows = block.strip().splitlines()[2:]
    return [(row.split(" | ")[0].lstrip("| "), row.rstrip(" |").rsplit(" | ", 1)[1]) for row in rows]


def test_the_readme_takes_its_steps_table_from_a_report(tmp_path):
    done = [(step, Section("", ""), 1.5 + k) for k, step in enumerate(STEPS)]
    assert readme_rows_from(done, tmp_path) == [(step.title, f"{1.5 + k:.1f}") for k, step in enumerate(STEPS)]


def test_a_step_the_report_was_made_without_is_listed_without_minutes(tmp_path):
    done = [(step, Section("", ""), 2.0) for step in STEPS[:-2] + STEPS[-1:]]
    rows = readme_rows_from(done, tmp_path)
    assert [title for title, _ in rows] == [step.title for step in STEPS]
    assert [minutes for _, minutes in rows] == ["2.0"] * (len(STEPS) - 2) + [NOT_IN_REPORT, "2.0"]


def test_the_readme_lists_every_step_of_make_reproduce():
    """The README's table (the last report's) holds every step, in order, whatever their minutes."""
    text = README.read_text()
    block = text.split(markers("reproduce", README_COMMAND)[0], 1)[1].split(markers("reproduce", README_COMMAND)[1])[0]
    titles = [line.split(" | ")[0].lstrip("| ") for line in block.strip().splitlines()[2:]]
    assert titles == [step.title for step in STEPS], f"run make reproduce SCALE=paper, then {README_COMMAND}"
