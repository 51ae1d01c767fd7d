"""The playback figure: the recorded voltage, and P, Q recorded against played back."""

from __future__ import annotations

from typing import Any

from loadbayes.plots.fit import pyplot

__all__ = ["plot_playback"]


def plot_playback(pb: Any, numbers: dict[str, Any], *, title: str = "") -> Any:
    """Three panels sharing time: V imposed, P and Q recorded (dots) and played back (line).

    Parameters
    ----------
    pb : loadbayes.export.andes.playback.Playback
        The playback.
    numbers : dict
        :func:`loadbayes.export.andes.playback.compare`'s output (RMS in the legends).
    title : str
        Figure title.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.
    """
    plt = pyplot()
    fig, axes = plt.subplots(3, 1, figsize=(7.5, 7.5), sharex=True)
    t = pb.t_s
    axes[0].plot(t, pb.v, ".", ms=3, color="0.3", label="recorded (imposed)")
    axes[0].plot(t, pb.v_load, "-", lw=1, color="C0", label="ANDES load bus")
    axes[0].set_ylabel("V (p.u.)")
    for ax, rec, sim, name in (
        (axes[1], pb.p_rec, pb.p_sim, "p"),
        (axes[2], pb.q_rec, pb.q_sim, "q"),
    ):
        rms = numbers[f"rms_{name}"]
        res = numbers.get(f"fit_residual_{name}")
        extra = "" if res is None else f", fit's noise {res:.4f}"
        ax.plot(t, rec, ".", ms=3, color="0.3", label="recorded")
        ax.plot(t, sim, "-", lw=1.2, color="C3", label=f"ANDES playback (RMS {rms:.4f}{extra})")
        ax.set_ylabel(f"{name.upper()} (p.u.)")
        ax.legend(loc="best", fontsize=8)
    axes[0].legend(loc="best", fontsize=8)
    axes[2].set_xlabel("t (s)")
    fig.suptitle(title or "recorded voltage played into the exported ANDES case", fontsize=10)
    fig.tight_layout()
    return fig
