"""The atomic tasks: one case per seeded instance of every template under tasks/ (ids like
`ubuntu-calc-sort_column[seed0]`; markers: platform, `atomic`, app)."""

from jarvis_pytest.plugin.session import assert_task_passed

JARVIS_TASKS = "atomic"


def test_atomic(jarvis_result):
    assert_task_passed(jarvis_result)
