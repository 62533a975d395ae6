"""Progress: silent unless a display is open; the CLI opens one only on a terminal without --json."""

from __future__ import annotations

import io

from tcamlab import progress


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_is_wanted_only_on_a_terminal_without_json():
    assert progress.wanted(stream=_Terminal())
    assert not progress.wanted(json_output=True, stream=_Terminal())
    assert not progress.wanted(stream=io.StringIO())  # a pipe or a file


def test_a_task_without_a_display_is_a_silent_no_op(capsys):
    with progress.task("fitting", total=3) as step:
        step()
        step(2, description="done")
    assert capsys.readouterr() == ("", "")


def test_a_task_inside_a_display_counts_its_steps_and_leaves_when_done():
    with progress.display(True):
        bar = progress._BAR.get()
        with progress.task("fitting candidate effects", total=3) as step:
            step()
            step(description="fitted initial-slack")
            (task,) = bar.tasks
            assert (task.completed, task.total, task.description) == (2, 3, "fitted initial-slack")
        assert bar.tasks == []
    assert progress._BAR.get() is None


def test_a_display_that_is_not_wanted_opens_nothing():
    with progress.display(False):
        assert progress._BAR.get() is None
