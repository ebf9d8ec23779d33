"""File generators: input files of tasks made on the host from slot values, then uploaded to the device.

A setup step ``{"type": "upload_file", "path": "...", "generator": "odt_document", "args": {...}}`` calls the
generator registered under that name with the step's (templated) arguments and uploads the bytes it returns, so
a task's documents, spreadsheets, images and media carry its instance's random values and nothing is downloaded
at run time. Generators are deterministic: the same arguments give the same bytes. Importing this package
registers all of them; each topic module (`documents.py`, ...) registers its own with `@generator("name")`.
"""

from jarvis_pytest.generators.registry import GENERATORS, generate, generator  # noqa: F401
from jarvis_pytest.generators import documents, images, media, presentations, spreadsheets, text  # noqa: F401,E402  (registers)
from jarvis_pytest.generators import rtf, windows_text  # noqa: F401,E402  (registers)
from jarvis_pytest.generators import android  # noqa: F401,E402  (registers)
