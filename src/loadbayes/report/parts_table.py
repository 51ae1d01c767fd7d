"""The table ``fit composite --model slm|cmld-lite`` prints: shares, feeder, motors, words.

One line per physical quantity of a model of parts (its median and interval, with the
unit and meaning the model gives in ``quantities``), then the words of
``fit/composite/describe_parts.py``: the negative sequence, what the prior decided.
"""

from __future__ import annotations

from typing import Any

__all__ = ["parts_lines"]

_ORDER = ("f_s", "f_motors", "f_m", "f_m_a", "f_m_b", "f_d", "f_el", "a1", "a2", "a3",
          "x_fd", "r_fd")  # fmt: skip
_MOTOR = ("rs", "x_prime", "x_open", "t_prime_s", "h_s", "t0", "mva")


def parts_lines(post: Any, table: Any, *, quantities: Any, hdi_prob: float = 0.95) -> list[str]:
    """The printed table of a parts model's fit (``table``: ``post.summary()``)."""
    q = dict(quantities)
    names = [n for n in _ORDER if n in table.index]
    for tag in ("", "_a", "_b", "_m"):
        names += [k + tag for k in _MOTOR if k + tag in table.index and k + tag not in names]
    names += [n for n in table.index if n.startswith("mva") and "_e" not in n and n not in names]
    names += [n for n in table.index if n in ("p0", "q0", "rho_p", "rho_q")]
    lo, hi = table.columns[2], table.columns[3]
    out = [f"{'quantity':<12} {'mean':>9} {f'{hdi_prob:.0%} interval':>22}  meaning"]
    for n in names:
        row = table.loc[n]
        unit, meaning = q.get(n, ("", ""))
        meaning = f"{meaning} ({unit})" if unit and unit != "-" else meaning
        out.append(f"{n:<12} {row['mean']:>9.4g} [{row[lo]:>9.4g}, {row[hi]:>9.4g}]  {meaning}")
    parts = post.extra_json.get("parts", {})
    ns = parts.get("negative_sequence", {}).get("summary")
    if ns:
        out.append(ns)
    return out
