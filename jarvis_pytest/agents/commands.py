"""`jarvis ground`: ground one instruction on one screenshot with one grounding model and print the pixel."""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from jarvis_pytest.agents.registry import load_grounder_class
from jarvis_pytest.errors import ConfigError
from jarvis_pytest.llm.client import ChatClient


def ground(args: argparse.Namespace) -> int:
    grounder_cls = load_grounder_class(args.model)
    image = Path(args.image)
    if not image.is_file():
        raise ConfigError("no such image", path=image, field="--image", fix="give a PNG screenshot")
    png = image.read_bytes()
    if not png.startswith(b"\x89PNG\r\n\x1a\n"):
        raise ConfigError("not a PNG file", path=image, field="--image", fix="convert the screenshot to PNG")
    served = args.model_name or os.environ.get("JARVIS_GROUNDER_MODEL") or grounder_cls.default_model
    api_key = args.api_key or os.environ.get("JARVIS_GROUNDER_API_KEY")
    with ChatClient(args.base_url, served, api_key=api_key, timeout=args.timeout,
                    max_retries=args.max_retries) as client:
        result = grounder_cls(client).ground(png, args.instruction, args.platform)
    if args.json:
        print(json.dumps({"x": result.x, "y": result.y}))
    else:
        print(f"x={result.x} y={result.y}  (model answer: {result.answer.strip()!r}; "
              f"image sent as {result.sent_size[0]}x{result.sent_size[1]})")
    return 0


def register(sub) -> None:
    p = sub.add_parser("ground", help="ground one instruction on one screenshot with a grounding model",
                       description="Ask a grounding model where an element is; prints the point in the "
                                   "screenshot's own pixels.")
    p.add_argument("--model", required=True, metavar="NAME",
                   help="grounding adapter: qwen3-vl, holo2, ui-tars-1.5, mai-ui, ui-venus, gui-owl, or module:Class")
    p.add_argument("--base-url", required=True, help="OpenAI-compatible base URL, e.g. http://127.0.0.1:8000/v1")
    p.add_argument("--api-key", default=None, help="API key (default: env JARVIS_GROUNDER_API_KEY)")
    p.add_argument("--model-name", default=None,
                   help="served model name (default: env JARVIS_GROUNDER_MODEL, else the adapter's model id)")
    p.add_argument("--platform", default="ubuntu", choices=("android", "windows", "ubuntu"),
                   help="platform of the screenshot (chooses GUI-Owl's mobile or desktop prompt); default ubuntu")
    p.add_argument("--image", required=True, help="the screenshot (PNG)")
    p.add_argument("--instruction", required=True, help="the element to find, e.g. 'the Save button'")
    p.add_argument("--timeout", type=float, default=120.0, help="seconds per request attempt (default 120)")
    p.add_argument("--max-retries", type=int, default=4, help="retries on 429/5xx/timeouts (default 4)")
    p.add_argument("--json", action="store_true", help='print {"x": int, "y": int} only')
    p.set_defaults(func=ground)
