r"""Which bays of a record feed a load: name rules, the user's first, then the defaults.

A recorder names its bays in the ``.cfg`` (the channels' ``ccbm`` field, or their names):
``1号主变_高压侧_201开关_I``, ``10kV出线3``, ``Feeder 2``, ``TX1 HV``. A rule is a text
pattern and a kind: the first rule whose pattern the bay's name holds (case-insensitive;
a pattern written ``re:...`` is a regular expression) gives the bay its kind. The kinds
``transformer``, ``feeder`` and ``load`` are loads and are fitted; ``line``, ``coupler``,
``generator``, ``capacitor``, ``bus``, or ``skip`` are not; a bay no rule matches is
``unknown`` and fitted too (a recorder's bay is most often a load), and the catalog says so.

The user's rules come from a TOML file (``--rules rules.toml``), either top-level keys or
a ``[bays]`` table, in file order::

    "主变" = "transformer"
    "出线" = "feeder"
    're:^T\d' = "transformer"   # a regular expression (a TOML literal string)
    "母联" = "skip"
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence

from loadbayes.io.errors import DataError

__all__ = ["DEFAULT_RULES", "LOAD_KINDS", "bay_kind", "is_load", "read_rules"]

#: Kinds that are a load (their events are fitted); ``unknown``: no rule matched.
LOAD_KINDS = ("transformer", "feeder", "load", "unknown")

#: The defaults, tried after the user's, in order (the more specific first: 出线 before 线).
DEFAULT_RULES: tuple[tuple[str, str], ...] = (
    ("母联", "coupler"),
    ("分段", "coupler"),
    ("coupler", "coupler"),
    ("发电", "generator"),
    ("机组", "generator"),
    ("gen", "generator"),
    ("电容", "capacitor"),
    ("电抗", "capacitor"),
    ("capacitor", "capacitor"),
    ("主变", "transformer"),
    ("变压器", "transformer"),
    ("transformer", "transformer"),
    ("trafo", "transformer"),
    ("re:(^|[^a-z])tx ?\\d*($|[^a-z])", "transformer"),
    ("re:(^|[^a-z])t\\d+($|[^a-z0-9])", "transformer"),
    ("出线", "feeder"),
    ("馈线", "feeder"),
    ("feeder", "feeder"),
    ("fdr", "feeder"),
    ("负荷", "load"),
    ("load", "load"),
    ("母线", "bus"),
    ("bus", "bus"),
    ("线", "line"),
    ("line", "line"),
)


def _matches(pattern: str, name: str) -> bool:
    if pattern.startswith("re:"):
        return re.search(pattern[3:], name, flags=re.IGNORECASE) is not None
    return pattern.lower() in name.lower()


def bay_kind(name: str, rules: Sequence[tuple[str, str]] = ()) -> str:
    """The kind of the bay named ``name``: the first rule that matches, user's then defaults.

    Examples
    --------
    >>> bay_kind("1号主变_高压侧_201开关_I")
    'transformer'
    >>> bay_kind("Bay 7", [("bay 7", "feeder")])
    'feeder'
    """
    for pattern, kind in (*rules, *DEFAULT_RULES):
        if _matches(pattern, name):
            return kind
    return "unknown"


def is_load(kind: str) -> bool:
    """Whether a bay of this kind is fitted."""
    return kind in LOAD_KINDS


def read_rules(path: str | os.PathLike[str] | None) -> list[tuple[str, str]]:
    """The rules of a TOML file (pattern = kind, in file order); none for None.

    Raises
    ------
    DataError
        Naming the file and the key, for a file that is not TOML, a kind that is not
        text, or a pattern that is not a valid regular expression.
    """
    if path is None:
        return []
    import tomllib

    name = os.fspath(path)
    try:
        with open(name, "rb") as fh:
            data = tomllib.load(fh)
    except FileNotFoundError:
        raise DataError("file not found", name) from None
    except tomllib.TOMLDecodeError as exc:
        raise DataError(f"not a TOML file of bay rules ({exc})", name) from None
    table = data.get("bays", data) if isinstance(data.get("bays"), dict) else data
    rules = []
    for pattern, kind in table.items():
        if not isinstance(kind, str) or not kind.strip():
            raise DataError(
                f'rule {pattern!r}: the kind must be text such as "transformer", "feeder", '
                f'"load" or "skip", not {kind!r}',
                name,
            )
        if pattern.startswith("re:"):
            try:
                re.compile(pattern[3:])
            except re.error as exc:
                raise DataError(
                    f"rule {pattern!r}: not a regular expression ({exc})", name
                ) from None
        rules.append((pattern, kind.strip().lower()))
    return rules
