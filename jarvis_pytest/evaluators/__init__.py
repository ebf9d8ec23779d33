"""Evaluators: parameterised checks of a task's final state (paper §3.1 "Dynamic Evaluation").

An evaluator is a plain function registered by name with `@evaluator("name")`. It receives the `FinalState` of
the subtask (devices, transfer drive, pulled files) and the subtask's rendered arguments, and returns a
`Verdict` whose reason says what was expected and what was found. Getters that pull state to the host live in
`state.py`; checks live in topic modules (`files.py`, ...). Importing this package registers all of them.
"""

from jarvis_pytest.evaluators.registry import EVALUATORS, Verdict, evaluator, get_evaluator  # noqa: F401
from jarvis_pytest.evaluators import browser, documents, files, images, media, presentations, settings, spreadsheets  # noqa: F401,E402,I001  (registers)
from jarvis_pytest.evaluators import desktop  # noqa: F401,E402  (registers)
from jarvis_pytest.evaluators import windows_registry  # noqa: F401,E402  (registers)
from jarvis_pytest.evaluators import text, rtf  # noqa: F401,E402  (registers)
from jarvis_pytest.evaluators import folders  # noqa: F401,E402  (registers)
from jarvis_pytest.evaluators import windows_files  # noqa: F401,E402  (registers)
from jarvis_pytest.evaluators import windows_processes  # noqa: F401,E402  (registers)
from jarvis_pytest.evaluators import android  # noqa: F401,E402  (registers)
from jarvis_pytest.evaluators import transfer  # noqa: F401,E402  (registers)
