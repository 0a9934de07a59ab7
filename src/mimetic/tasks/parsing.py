"""Text forms of structured options (``joy=0.7``, ``0.5:joy+surprise=0.3``, ``jaw_open@1.25=0.3``).

Options that hold pairs or key specs are written as short text items on the command line and in
batch manifests. Each parser here takes the items and returns the option's value, or raises
``ValueError`` whose message shows the expected form with an example (front ends show it as their
usage error).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable

_CHANNEL_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_.\-]*$")


def _number(text: str) -> float:
    number = float(text)
    if not math.isfinite(number):
        raise ValueError(text)
    return number


def name_value(item: str, form: str = "NAME=VALUE", example: str = "nose_length=1.05") -> tuple[str, float]:
    """``"NAME=VALUE"`` → (name, value)."""
    name, sep, value = str(item).partition("=")
    try:
        number = _number(value)
    except ValueError:
        sep = ""
    if not sep or not name.strip():
        raise ValueError(f"{item!r}: expected {form}, e.g. {example}")
    return name.strip(), number


def name_values(items: Iterable[str]) -> tuple[tuple[str, float], ...]:
    """``NAME=VALUE`` items (head parameters) → ((name, value), ...)."""
    return tuple(name_value(item) for item in items)


def channel_values(items: Iterable[str]) -> tuple[tuple[str, float], ...]:
    """``CHANNEL=VALUE`` items → ((channel, value), ...)."""
    return tuple(name_value(item, "CHANNEL=VALUE", "jaw_open=0.2") for item in items)


def weights(items: Iterable[str]) -> tuple[tuple[str, float], ...]:
    """``NAME`` or ``NAME=WEIGHT`` items (expressions to blend) → ((name, weight), ...)."""
    out = []
    for item in items:
        if "=" in item:
            out.append(name_value(item, "NAME or NAME=WEIGHT", "joy=0.7"))
        elif not item.strip():
            raise ValueError("an empty expression name")
        else:
            out.append((item.strip(), 1.0))
    return tuple(out)


def pose_spec(item: str) -> tuple[float, tuple[tuple[str, float], ...] | None]:
    """``TIME:EXPR[=W][+EXPR[=W]...]`` or ``TIME:rest`` → (time_s, ((expression, weight), ...) or None)."""
    time_text, sep, rest = item.partition(":")
    try:
        time_s = _number(time_text.strip().removesuffix("s"))
    except ValueError:
        sep = ""
    if not sep or not rest.strip():
        raise ValueError(f"{item!r}: expected TIME:EXPRESSION[=WEIGHT][+...], e.g. 0.5:joy=0.8")
    if rest.strip() == "rest":
        return time_s, None
    blend = []
    for part in rest.split("+"):
        name, eq, value = part.partition("=")
        try:
            blend.append((name.strip(), _number(value) if eq else 1.0))
        except ValueError:
            raise ValueError(f"{item!r}: weight {value!r} of {name.strip()!r} is not a number") from None
    return time_s, tuple(blend)


def pose_specs(items: Iterable[str]) -> tuple[tuple[float, tuple[tuple[str, float], ...] | None], ...]:
    """``--pose`` items → ((time_s, blend or None), ...)."""
    return tuple(pose_spec(item) for item in items)


def key_spec(spec: str) -> tuple[str, float, float]:
    """``"jaw_open@1.25=0.3"`` → ``("jaw_open", 1.25, 0.3)``: channel, time in seconds, value.

    The time may end in "s" (``jaw_open@1.25s=0.3``); spaces around ``@`` and ``=`` are allowed.
    """
    usage = f"key {spec!r} must look like CHANNEL@TIME_S=VALUE, e.g. jaw_open@1.25=0.3"
    if (
        not isinstance(spec, str)
        or spec.count("@") != 1
        or spec.count("=") != 1
        or spec.index("@") > spec.index("=")
    ):
        raise ValueError(usage)
    channel, rest = spec.split("@")
    time_text, value_text = rest.split("=")
    channel, time_text, value_text = channel.strip(), time_text.strip(), value_text.strip()
    if not _CHANNEL_NAME.match(channel):
        raise ValueError(f"{usage}; {channel!r} is not a channel name")
    time_text = time_text.removesuffix("s").strip()
    numbers = []
    for text, what in ((time_text, "time"), (value_text, "value")):
        try:
            numbers.append(_number(text))
        except ValueError:
            raise ValueError(f"{usage}; the {what} {text!r} is not a finite number") from None
    return channel, numbers[0], numbers[1]


def key_specs(items: Iterable[str]) -> tuple[tuple[str, float, float], ...]:
    """``--key`` items → ((channel, time_s, value), ...)."""
    return tuple(key_spec(item) for item in items)


def proxy_spec(item: str | int) -> str | int:
    """``auto``, ``off`` or a skin vertex count (``20000``) → "auto", "off" or the count: the physical
    engines' proxy (``engines.volume.proxy_size`` checks the count's range)."""
    text = str(item).strip().lower().replace("_", "")
    if text in ("auto", "off"):
        return text
    if not text.isdigit():
        raise ValueError(f"{item!r}: expected auto, off or a skin vertex count, e.g. 20000")
    return int(text)
