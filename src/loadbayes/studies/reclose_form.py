"""The reclose's miss as model form, in the real-record study's table and words.

:func:`form_rows` writes ``fit/composite/model_error.held_out_error``'s numbers as the
table's rows of one model (the first fault's AR(1) model error and its share of that
fault's error; the reclose's band with it; the reclose's mean square split), and
:func:`form_words` says where most of a channel's held-out error is error the first
fault never showed: a band the stated model supports does not cover it.
"""

from __future__ import annotations

__all__ = ["form_rows", "form_words"]


def form_rows(name: str, form: dict, scale: float) -> dict[str, str]:
    """The table's rows of ``model_error.held_out_error``: the model error and its split."""

    def fit(ch):
        d = form[ch]["disc"]
        return f"{ch.upper()} {100 * d.sd_d / scale:.2f}, {d.rho:.2f}, {d.share:.0%}"

    def split(ch):
        s = form[ch]["split"]
        return (f"{ch.upper()} {s['noise']:.0%}, {s['parameters']:.0%}, {s['form_seen']:.0%}, "
                f"{s['beyond']:+.0%}")  # fmt: skip

    return {
        f"{name}: first fault's model error: AR(1) sd (% of P0), rho, share of its error":
            f"{fit('p')}; {fit('q')}",
        f"{name}: reclose in the 95% band with that model error (P, Q)":
            f"{form['p']['coverage']:.0%}, {form['q']['coverage']:.0%}",
        f"{name}: reclose's mean square: noise, parameters, model form as on the first "
        "fault, beyond it": f"{split('p')}; {split('q')}",
    }  # fmt: skip


def form_words(form: dict) -> list[str]:
    """Where most of a channel's held-out error is what the fitted event never showed."""
    out = []
    for name, f in form.items():
        for ch in ("p", "q"):
            s = f[ch]["split"]
            if s.get("beyond", 0.0) >= 0.5:
                out.append(f"{name}: {s['beyond']:.0%} of the mean square of its miss of the "
                           f"reclose's {ch.upper()} is error the first fault never showed (its "
                           f"model form there, an AR(1) error, is {s['form_seen']:.0%}, the "
                           f"recorder's noise {s['noise']:.0%}); a band with the first fault's "
                           f"model error covers {f[ch]['coverage']:.0%} of the reclose's "
                           f"{ch.upper()}: the stated model supports no wider band")  # fmt: skip
    return out
