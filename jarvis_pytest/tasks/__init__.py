"""The typed task model (paper §3.1, §4): type system, templates, instances, task graphs and composition.

Modules: ``types`` (slot type hierarchy), ``model`` (pydantic models), ``templating`` (``{{slot}}``),
``library`` (template files), ``instances`` (sampling and M(v_I)), ``transfer`` (the built-in transfer task),
``graph`` (graph checks and SW/MI/MD), ``instruction`` (merged instruction), ``compose`` (Algorithm 1),
``dataset`` (dataset files), ``llm_steps`` (optional LLM rewrite and judge) and ``commands`` (the CLI). The
pytest plugin takes `Task` models straight from ``instances`` and ``dataset``.
"""

from jarvis_pytest.tasks.compose import compose  # noqa: F401
from jarvis_pytest.tasks.dataset import load_dataset, load_tasks, write_dataset  # noqa: F401
from jarvis_pytest.tasks.instances import atomic_instances, atomic_task, materialise  # noqa: F401
from jarvis_pytest.tasks.library import Library, load_library  # noqa: F401
from jarvis_pytest.tasks.model import Subtask, Task, TaskTemplate  # noqa: F401
from jarvis_pytest.tasks.types import TypeSystem, load_types  # noqa: F401
