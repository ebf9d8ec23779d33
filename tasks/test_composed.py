"""The composed tasks of the dataset files under tasks/composed/ (markers: platforms, `sw`/`mi`/`md`)."""

from jarvis_pytest.plugin.session import assert_task_passed

JARVIS_TASKS = "composed"


def test_composed(jarvis_result):
    assert_task_passed(jarvis_result)
