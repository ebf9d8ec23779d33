"""Dates for evaluators: a date as people and programs write it, and "today" by the device's own clock.

Today is the device's, never the host's: an application inserts the date of the clock it runs under (WordPad's
Insert > Date and time reads the local time of the Windows it runs on), so the evaluator asks that device at
evaluation (`PlatformSpec.today_command`) and compares exactly. The only other day that counts is one the device's
clock passed since set-up: a template that records the device's date at set-up in a file it lists under
`baseline` lets `allowed_days` accept every day from then to now (the clock crossed midnight while the agent
worked), and the reason says so.
"""

from __future__ import annotations

import datetime as _dt
import re

from jarvis_pytest.devices.platforms import spec
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.evaluators.state import FinalState

DATE_FORMATS = ("%m/%d/%Y", "%m/%d/%y", "%d/%m/%Y", "%d.%m.%Y", "%Y-%m-%d", "%A, %B %d, %Y", "%B %d, %Y",
                "%A, %d %B %Y", "%d %B %Y", "%a, %b %d, %Y", "%b %d, %Y", "%d %b %Y", "%d-%b-%y", "%d-%b-%Y")
TIME = re.compile(r"\s*,?\s*\d{1,2}:\d{2}(:\d{2})?(\s*[AaPp]\.?[Mm]\.?)?$")
LABEL = re.compile(r"^(date|today|dated|datum)\s*:?\s*", re.I)
ISO_DAY = re.compile(r"\b(\d{4}-\d{2}-\d{2})\b")


def parse_date(text: str) -> _dt.date | None:
    """The date `text` names in one of WordPad's (Insert > Date and time) or other common written forms, a label
    such as "Date:" before it and a time of day after it allowed; None when it names none."""
    text = TIME.sub("", LABEL.sub("", text.strip()).rstrip("."))
    for fmt in DATE_FORMATS:
        try:
            return _dt.datetime.strptime(text, fmt).date()
        except ValueError:
            continue
    return None


def device_today(state: FinalState, platform: str | None = None) -> _dt.date:
    """The local date of the device's own clock now. An InfrastructureError when the device does not say it."""
    res = state.run(spec(platform or state.platform).today_command, platform)
    found = ISO_DAY.search(res.stdout or "")
    if res.returncode != 0 or not found:
        raise InfrastructureError(f"the device did not tell its date (exit {res.returncode}): "
                                  f"{(res.stdout + res.stderr)[-300:]!r}")
    return _dt.date.fromisoformat(found.group(1))


def allowed_days(state: FinalState, record: str | None, platform: str | None = None
                 ) -> tuple[list[_dt.date], str]:
    """The days an action taken since set-up may have been dated by the device's clock, and how that was decided:
    today alone, or every day from the set-up day `record` holds (a file with the device's date at set-up, listed
    under `baseline`) to today when the device's clock crossed midnight meanwhile."""
    today = device_today(state, platform)
    data = state.baseline(record, platform) if record else None
    found = ISO_DAY.search(data.decode("ascii", errors="replace")) if data else None
    if found is None:
        why = "no record of the set-up day" if record else "no set-up day asked for"
        return [today], f"today by the device's clock, {today} ({why}: no other day counts)"
    start = _dt.date.fromisoformat(found.group(1))
    if start >= today:
        return [today], f"today by the device's clock, {today} (set up the same day)"
    days = [start + _dt.timedelta(days=i) for i in range((today - start).days + 1)]
    return days, (f"today by the device's clock, {today}, or {', '.join(map(str, days[:-1]))}: the device's clock "
                  f"crossed midnight since set-up on {start}")
