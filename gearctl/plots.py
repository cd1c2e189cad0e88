"""Figures. Only this module and :mod:`gearctl.cli` import matplotlib.

Every function takes computed data (a result dataclass) and returns a :class:`matplotlib.figure.Figure`;
nothing is shown or written unless the caller saves the figure (:func:`save`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from .stiffness import COMPONENTS, MeshStiffness, ToothDeflections

__all__ = [
    "plot_stiffness", "plot_simulation", "plot_tracking", "plot_bode", "plot_step", "plot_bench_errors",
    "plot_bench_bars", "plot_precision", "save",
]

_LABELS = {
    "bending_cos": r"$\delta_{bp}$ bending by $F\cos\phi$",
    "bending_sin": r"$\delta_{bn}$ bending by $F\sin\phi$",
    "shear": r"$\delta_s$ shear",
    "foundation": r"$\delta_f$ foundation",
    "hertz": r"$\delta_h$ Hertz",
    "total": r"$\delta_t$ total",
}


def save(fig: Figure, path: str | Path) -> Path:
    """Write a figure to ``path`` (format from the suffix; PNG without one, under that very name: matplotlib
    would append ``.png``, and ``--plot FILE`` said "wrote FILE" of a file it did not write), creating the folder;
    return the path.

    Parameters
    ----------
    fig : Figure
        The figure (written at 120 dpi).
    path : str or Path
        The file; its suffix picks the format.

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120, bbox_inches="tight", format=None if path.suffix else "png")
    return path


def plot_stiffness(deflections: ToothDeflections, mesh: MeshStiffness, *, title: str = "") -> Figure:
    """Report Figures 8–11: deflections of each gear, tooth stiffnesses and the mesh stiffness.

    Parameters
    ----------
    deflections : ToothDeflections
        From :func:`gearctl.stiffness.tooth_deflections` (one tooth pair, path of contact C → D).
    mesh : MeshStiffness
        From :func:`gearctl.stiffness.mesh_stiffness` (one mesh cycle C → F).
    title : str
        Figure title.
    """
    fig = Figure(figsize=(11, 8), layout="constrained")
    axs = fig.subplots(2, 2)
    th = deflections.theta1
    for ax, d, name in ((axs[0, 0], deflections.gear1, "gear 1 (Fig. 8)"), (axs[0, 1], deflections.gear2,
                                                                            "gear 2 (Fig. 9)")):
        for key in (*COMPONENTS, "total"):
            ax.plot(th, d[key] * 1e9, label=_LABELS[key], lw=2.0 if key == "total" else 1.2)
        ax.set(xlabel=r"$\vartheta_1$ [rad]", ylabel="deflection per unit load [nm/N]", title=f"Deflection, {name}")
        ax.grid(True, alpha=0.3)
    axs[0, 0].legend(fontsize=8)
    ax = axs[1, 0]
    ax.plot(th, deflections.stiffness1, label="$k_1$ tooth of gear 1")
    ax.plot(th, deflections.stiffness2, label="$k_2$ tooth of gear 2")
    ax.plot(th, deflections.pair_stiffness, label=r"$k_1 k_2/(k_1+k_2)$ tooth pair", lw=2)
    ax.set(xlabel=r"$\vartheta_1$ [rad]", ylabel="stiffness [N/m]", title="Tooth stiffness (Fig. 10)", yscale="log")
    ax.grid(True, alpha=0.3, which="both")
    ax.legend(fontsize=8)
    ax = axs[1, 1]
    ax.plot(mesh.theta1, mesh.K, label="K (eq. 21)")
    ax.axhline(mesh.mean, color="k", ls="--", label=f"mean {mesh.mean:.4e} N/m")
    ax.set(xlabel=r"$\vartheta_1$ [rad]", ylabel="mesh stiffness [N/m]", title="Mesh stiffness, one cycle (Fig. 11)")
    ax.set_ylim(0, 1.1 * np.max(mesh.K))
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    if title:
        fig.suptitle(title)
    return fig




def plot_simulation(results: dict[str, Any], *, title: str = "") -> Figure:
    """Angles, velocities and relative displacement of one or more runs on common axes (Figs 12–21).

    Parameters
    ----------
    results : dict of str to SimulationResult
        Label (e.g. ``"improved"``, ``"Yang-Sun"``) to result; all are drawn on the same axes.
    title : str
        Figure title.
    """
    fig = Figure(figsize=(11, 10), layout="constrained")
    axs = fig.subplots(3, 2)
    first = next(iter(results.values()))
    n = first.plant.n_stages
    w = n + 1  # shafts: 0 the motor, n the load
    # a train: the motor and the load shafts, each stage's gap over its backlash and its mesh force
    one, last = ("1", "2") if n == 1 else ("0", str(n))
    motor, load = ("gear 1", "gear 2") if n == 1 else ("the motor shaft", "the load shaft")
    panels = [
        (axs[0, 0], lambda r: r.x[0], rf"$\theta_{one}$ [rad]", f"Angular displacement of {motor}"),
        (axs[0, 1], lambda r: r.x[w - 1], rf"$\theta_{last}$ [rad]", f"Angular displacement of {load}"),
        (axs[1, 0], lambda r: r.x[w], rf"$\dot\theta_{one}$ [rad/s]", f"Angular velocity of {motor}"),
        (axs[1, 1], lambda r: r.x[2 * w - 1], rf"$\dot\theta_{last}$ [rad/s]", f"Angular velocity of {load}"),
    ]
    styles = ["-", "--", ":", "-."]
    for (label, res), ls in zip(results.items(), styles * 4, strict=False):
        for ax, get, ylabel, name in panels:
            ax.plot(res.t * 1e3, get(res), ls, label=label, lw=1.2)
            ax.set(xlabel="t [ms]", ylabel=ylabel, title=name)
        s_all, f_all = np.atleast_2d(res.s), np.atleast_2d(res.force)
        for i in range(n):
            tag = label if n == 1 else f"{label}, stage {i + 1}"
            if n == 1:
                axs[2, 0].plot(res.t * 1e3, s_all[i] * 1e3, ls, label=tag, lw=1.2)
            else:
                b_i = res.plant.backlashes[i]
                axs[2, 0].plot(res.t * 1e3, s_all[i] / b_i if b_i > 0 else s_all[i] * 0.0, ls, label=tag, lw=1.2)
            axs[2, 1].plot(res.t * 1e3, f_all[i], ls, label=tag, lw=1.2)
    if n == 1:
        axs[2, 0].set(xlabel="t [ms]", ylabel="s [mm]", title="Relative displacement along the line of action")
        lim = first.plant.backlash * 1e3
    else:
        axs[2, 0].set(xlabel="t [ms]", ylabel="$s_i / b_i$",
                      title="Each stage's relative displacement over its backlash")
        lim = 1.0
    axs[2, 1].set(xlabel="t [ms]", ylabel="F [N]", title="Contact force (front flank positive)")
    for sgn in (1, -1):
        axs[2, 0].axhline(sgn * lim, color="k", lw=0.6, ls=":")
    for ax in axs.flat:
        ax.grid(True, alpha=0.3)
    axs[0, 0].legend()
    if n > 1:
        axs[2, 0].legend(fontsize=8)
    if title:
        fig.suptitle(title)
    return fig


def plot_tracking(results: dict[str, Any], *, title: str = "") -> Figure:
    """Reference and load angle, tracking error, motor torque and gap state of closed-loop runs.

    Parameters
    ----------
    results : dict of str to ClosedLoopResult
        Label to run; all on common axes.
    title : str
        Figure title.
    """
    fig = Figure(figsize=(11, 10), layout="constrained")
    axs = fig.subplots(4, 1, sharex=True)
    first = next(iter(results.values()))
    axs[0].plot(first.t, first.reference, "k", lw=2, label="reference")
    n = first.plant.n_stages
    for label, r in results.items():
        axs[0].plot(r.t, r.x[r.plant.n_stages], label=label)  # the load shaft (shaft n)
        axs[1].plot(r.t, r.error * 1e3, label=label)
        axs[2].step(r.t, r.torque, where="post", label=label)
        s_all = np.atleast_2d(r.s)
        if r.plant.n_stages == 1:
            axs[3].plot(r.t, s_all[0] * 1e6, label=label)
        else:  # each stage over its own backlash
            for i, b_i in enumerate(r.plant.backlashes):
                axs[3].plot(r.t, s_all[i] / b_i if b_i > 0 else s_all[i] * 0.0, label=f"{label}, stage {i + 1}")
    lim = first.plant.backlash * 1e6 if n == 1 else 1.0
    for sgn in (1, -1):
        axs[3].axhline(sgn * lim, color="k", lw=0.6, ls=":")
    load = r"$\theta_2$" if n == 1 else rf"$\theta_{n}$"
    axs[0].set(ylabel=f"load angle {load} [rad]", title="Reference and load angle")
    axs[1].set(ylabel="error [mrad]", title=f"Tracking error r - {load}")
    axs[2].set(ylabel="motor torque [N m]", title="Motor torque")
    if n == 1:
        axs[3].set(ylabel=r"s [$\mu$m]", xlabel="t [s]", title="Gap state: relative displacement (contact beyond ±b)")
    else:
        axs[3].set(ylabel="$s_i / b_i$", xlabel="t [s]", title="Gap state of each stage (contact beyond ±1)")
    for ax in axs:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="upper right")
    if title:
        fig.suptitle(title)
    return fig


def _channel(sys: Any, label: str, output: str | None, input: str | None) -> tuple[Any, str, str]:
    """``sys[output, input]`` by signal name (default: the first output and input), else InputError naming the
    signal and the system's names (a train's models name the motor ``theta0``, ``xi0``: the pair's ``theta1``,
    ``xi1`` defaults used to fail there with ``ValueError: 'xi1' is not in list``)."""
    from .errors import InputError

    outs, ins = list(sys.output_labels), list(sys.input_labels)
    output = outs[0] if output is None else output
    input = ins[0] if input is None else input
    for field, name, names in (("output", output, outs), ("input", input, ins)):
        if name not in names:
            raise InputError(f"{field} = {name!r} is not a signal of system {label!r}: expected one of "
                             f"{', '.join(names)}", field=field)
    return sys[outs.index(output), ins.index(input)], output, input


def plot_bode(systems: dict[str, Any], *, output: str | None = None, input: str | None = None,
              omega: Any = None, title: str = "") -> Figure:
    """Bode diagram of one channel of several python-control systems on common axes.

    Parameters
    ----------
    systems : dict of str to control.LTI
        Label to system (e.g. the contact and separation models); the channel is picked by signal name.
    output, input : str, optional
        Signal names of the channel (default: each system's first output and input, the motor angle and the motor
        torque of the mode models: ``theta1``, ``xi1`` on a pair, ``theta0``, ``xi0`` on a train).
    omega : array_like, optional
        Frequencies [rad/s] (default: 0.1 Hz to 3x the highest pole).
    title : str
        Figure title.

    Raises
    ------
    InputError
        If ``output`` or ``input`` is not a signal of a system.
    """
    import control as ct
    import numpy as np

    if omega is None:
        wmax = max(float(np.max(np.abs(sys.poles()))) for sys in systems.values())
        omega = np.logspace(np.log10(2 * np.pi * 0.1), np.log10(3 * max(wmax, 10.0)), 2000)
    fig = Figure(figsize=(9, 7), layout="constrained")
    ax_m, ax_p = fig.subplots(2, 1, sharex=True)
    for label, sys in systems.items():
        sub, output, input = _channel(sys, label, output, input)
        resp = ct.frequency_response(sub, omega)
        mag, phase = np.squeeze(resp.magnitude), np.squeeze(resp.phase)
        ax_m.semilogx(omega / (2 * np.pi), 20 * np.log10(mag), label=label)
        ax_p.semilogx(omega / (2 * np.pi), np.degrees(np.unwrap(phase)), label=label)
    ax_m.set(ylabel="magnitude [dB]", title=f"{input} -> {output}")
    ax_p.set(ylabel="phase [deg]", xlabel="frequency [Hz]")
    for ax in (ax_m, ax_p):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    if title:
        fig.suptitle(title)
    return fig


def plot_step(systems: dict[str, Any], *, output: str | None = None, input: str | None = None, T: Any = None,
              title: str = "") -> Figure:
    """Step responses of one channel of several python-control systems on common axes.

    ``output``, ``input``: signal names as :func:`plot_bode` takes them (default: the first of each system).

    Parameters
    ----------
    systems : dict
        ``label -> system`` (python-control LTI systems).
    output : str, optional
        Output signal name (default: the first system's first output).
    input : str, optional
        Input signal name (default: the first system's first input).
    T : array_like or float, optional
        Time vector or final time [s], as :func:`control.step_response` takes it (default: its choice).
    title : str
        Figure title.

    Returns
    -------
    Figure

    Raises
    ------
    InputError
        For an ``output`` or ``input`` that is not a signal of a system (named).
    """
    import control as ct
    import numpy as np

    fig = Figure(figsize=(9, 5), layout="constrained")
    ax = fig.subplots()
    for label, sys in systems.items():
        sub, output, input = _channel(sys, label, output, input)
        resp = ct.step_response(sub, T=T)
        ax.plot(resp.time * 1e3, np.squeeze(resp.outputs), label=label)
    ax.set(xlabel="t [ms]", ylabel=output, title=f"Step of {input} -> {output}")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    if title:
        fig.suptitle(title)
    return fig


def plot_bench_errors(traces: dict[tuple[str, str], dict[str, Any]], *, reference: str) -> Figure:
    """Tracking error of every controller on one reference, one panel per controller, plants on common axes.

    Parameters
    ----------
    traces : dict
        From :func:`gearctl.bench.error_traces`: ``(controller, reference) -> {plant: (t, error)}``.
    reference : str
        The reference to draw.
    """
    ctrls = [c for (c, r) in traces if r == reference]
    fig = Figure(figsize=(10, 2.6 * max(len(ctrls), 1)), layout="constrained")
    axs = fig.subplots(max(len(ctrls), 1), 1, sharex=True, squeeze=False)[:, 0]
    for ax, c in zip(axs, ctrls, strict=False):
        for plant, (t, e) in traces[(c, reference)].items():
            ax.plot(t, e * 1e3, label=plant, lw=1.0)
        ax.set(ylabel="error [mrad]", title=f"{c}: load-angle error, {reference}")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="upper right")
    axs[-1].set_xlabel("t [s]")
    return fig


def plot_bench_bars(result: dict[str, Any]) -> Figure:
    """RMS load-angle error by controller and plant, one panel per reference (log scale).

    Parameters
    ----------
    result : dict
        What :func:`gearctl.bench.run_bench` returned; its runs on their own design that ran (``ok``) are drawn.

    Returns
    -------
    Figure
    """
    import numpy as np

    runs = [r for r in result["runs"] if r["design"] == "improved" and r.get("ok")]
    refs = list(dict.fromkeys(r["reference"] for r in runs))
    ctrls = list(dict.fromkeys(r["controller"] for r in runs))
    plants = list(dict.fromkeys(r["plant"] for r in runs))
    cell = {(r["controller"], r["reference"], r["plant"]): r["rms_error"] for r in runs}
    fig = Figure(figsize=(4.2 * max(len(refs), 1), 4.5), layout="constrained")
    axs = fig.subplots(1, max(len(refs), 1), squeeze=False)[0]
    width = 0.8 / max(len(plants), 1)
    x = np.arange(len(ctrls))
    for ax, ref in zip(axs, refs, strict=False):
        positive = False
        for k, p in enumerate(plants):
            vals = [cell.get((c, ref, p), np.nan) * 1e6 for c in ctrls]
            vals = [v if v > 0 else np.nan for v in vals]  # an exact zero (a loop that never moved) has no log
            positive = positive or any(np.isfinite(vals))
            ax.bar(x + (k - (len(plants) - 1) / 2) * width, vals, width, label=p)
        ax.set_xticks(x, ctrls, rotation=20, ha="right")
        ax.set(yscale="log" if positive else "linear", ylabel="RMS error [urad]", title=ref)
        ax.grid(True, axis="y", alpha=0.3, which="both")
    axs[0].legend(fontsize=8)
    return fig


def plot_precision(result: Any, *, title: str = "") -> Figure:
    """ISO 230-2 plot: deviations per target and direction, means and ± 2 s bands.

    Parameters
    ----------
    result : PrecisionResult
        From :func:`gearctl.precision.precision_test`.
    title : str
        Figure title.
    """
    import numpy as np

    st = result.stats
    P = result.targets
    fig = Figure(figsize=(9, 5.5), layout="constrained")
    ax = fig.subplots()
    n = result.deviations_up.shape[1]
    for j in range(n):
        ax.plot(P, result.deviations_up[:, j] * 1e6, "^", color="C0", alpha=0.5, label="approach +" if j == 0 else None)
        ax.plot(P, result.deviations_down[:, j] * 1e6, "v", color="C3", alpha=0.5,
                label="approach -" if j == 0 else None)
    for mean, s, color, lab in ((st["mean_up"], st["s_up"], "C0", "+"), (st["mean_down"], st["s_down"], "C3", "-")):
        ax.plot(P, np.asarray(mean) * 1e6, "-", color=color, label=f"mean {lab}")
        ax.fill_between(P, (np.asarray(mean) - 2 * np.asarray(s)) * 1e6, (np.asarray(mean) + 2 * np.asarray(s)) * 1e6,
                        color=color, alpha=0.15)
    ax.plot(P, np.asarray(st["mean_bidirectional"]) * 1e6, "k--", label="mean bidirectional")
    ax.set(xlabel="target position [rad]", ylabel="deviation [urad]",
           title=title or f"ISO 230-2: B = {st['reversal_value'] * 1e6:.1f} urad, "
                          f"R = {st['repeatability'] * 1e6:.1f} urad, "
                          f"A = {st['accuracy'] * 1e6:.1f} urad")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return fig


# --- robustness sweeps (gearctl.sweep) ------------------------------------------------------------------

__all__ += ["plot_sweep_scatter", "plot_sweep_histogram", "plot_sweep_map", "plot_sweep_compare"]


def _sweep_label(result: Any, key: str) -> str:
    v = next((v for v in result.vary if v.key == key), None)
    unit = "" if v is None or v.unit == "1" else f" [{v.unit}]"
    return f"{key}{unit}"


def plot_sweep_scatter(result: Any, key: str) -> Figure:
    """RMS and max load-angle error of every run against one varied key (log scale).

    Runs with a limit cycle are ringed; failed runs are drawn at the top of the panel as red crosses.

    Parameters
    ----------
    result : SweepResult
        From :func:`gearctl.sweep.sweep`.
    key : str
        A varied key.
    """
    x = result.column(key)
    ok = np.array([r["status"] == "ok" for r in result.runs])
    cyc = np.array([bool(r.get("limit_cycle")) for r in result.runs])
    fig = Figure(figsize=(7.5, 4.5), layout="constrained")
    ax = fig.subplots()
    for name, marker, color in (("rms_error", "o", "C0"), ("max_error", ".", "C1")):
        y = result.column(name) * 1e6
        ax.plot(x[ok], y[ok], marker, ms=3, alpha=0.6, color=color, ls="none", label=name.replace("_", " "))
        if np.any(ok & cyc):
            ax.plot(x[ok & cyc], y[ok & cyc], "o", mfc="none", mec="k", ms=6, ls="none",
                    label="limit cycle" if name == "rms_error" else None)
    if np.any(~ok):
        top = np.nanmax(result.column("max_error")[ok]) * 1e6 if np.any(ok) else 1.0
        ax.plot(x[~ok], np.full(int(np.sum(~ok)), top * 1.5), "x", color="C3", ls="none", label="failed")
    nominal = result.settings.get("nominal", {}).get(key)
    if nominal:
        ax.axvline(nominal, color="0.5", ls="--", lw=1, label="nominal")
    st = result.settings
    ax.set(xlabel=_sweep_label(result, key), ylabel="load-angle error [urad]", yscale="log",
           title=f"{st['controller']} on {st['model']}: {len(result.runs)} runs, {st['reference']}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def plot_sweep_histogram(result: Any) -> Figure:
    """Histograms of the RMS and max load-angle error over the runs that ran to their end (log bins).

    Parameters
    ----------
    result : SweepResult
        From :func:`gearctl.sweep.sweep`.

    Returns
    -------
    Figure
    """
    from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter

    fig = Figure(figsize=(9, 4), layout="constrained")
    axs = fig.subplots(1, 2)
    ok = np.array([r["status"] == "ok" for r in result.runs])
    for ax, name in zip(axs, ("rms_error", "max_error"), strict=True):
        y = result.column(name)[ok] * 1e6
        y = y[np.isfinite(y) & (y > 0)]
        if y.size:
            lo, hi = y.min(), y.max()
            bins = np.geomspace(lo, hi * (1 + 1e-9), 30) if hi > lo else 10
            ax.hist(y, bins=bins, color="C0", alpha=0.8)
            for q, ls in ((50, "-"), (95, "--"), (99, ":")):
                ax.axvline(np.percentile(y, q), color="k", ls=ls, lw=1, label=f"p{q}")
            ax.set_xscale("log")
            ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
            ax.xaxis.set_major_formatter(FormatStrFormatter("%g"))
            ax.xaxis.set_minor_formatter(NullFormatter())
            ax.legend(fontsize=8)
        ax.set(xlabel=f"{name.replace('_', ' ')} [urad]", ylabel="runs")
        ax.grid(True, alpha=0.3, which="both")
    fig.suptitle(f"{result.settings['controller']} on {result.settings['model']}: {len(result.runs)} runs "
                 f"({int(np.sum(~ok))} failed)")
    return fig


def plot_sweep_map(result: Any, metric: str = "rms_error") -> Figure:
    """A two-key grid's figure as a colour map (log colour scale, failed cells blank).

    Parameters
    ----------
    result : SweepResult
        A grid sweep over two keys.
    metric : str
        A run figure (default ``rms_error``), drawn in urad.
    """
    from matplotlib.colors import LogNorm

    from .sweep import grid_axes

    keys, axes, values = grid_axes(result, metric)
    fig = Figure(figsize=(7.5, 5.5), layout="constrained")
    ax = fig.subplots()
    z = values.T * 1e6
    finite = z[np.isfinite(z) & (z > 0)]
    norm = LogNorm(vmin=finite.min(), vmax=finite.max()) if finite.size and finite.max() > finite.min() else None
    mesh = ax.pcolormesh(axes[0], axes[1], z, shading="nearest", norm=norm, cmap="viridis")
    fig.colorbar(mesh, ax=ax, label=f"{metric.replace('_', ' ')} [urad]")
    if finite.size > 3 and norm is not None:
        cs = ax.contour(axes[0], axes[1], z, levels=np.geomspace(finite.min(), finite.max(), 6)[1:-1], colors="w",
                        linewidths=0.8)
        ax.clabel(cs, fmt="%.3g", fontsize=7)
    for k, axis in ((keys[0], "x"), (keys[1], "y")):
        nominal = result.settings.get("nominal", {}).get(k)
        if nominal:
            (ax.axvline if axis == "x" else ax.axhline)(nominal, color="r", ls="--", lw=1)
    ax.set(xlabel=_sweep_label(result, keys[0]), ylabel=_sweep_label(result, keys[1]),
           title=f"{result.settings['controller']} on {result.settings['model']} (red: nominal)")
    return fig


def plot_sweep_compare(comparison: dict[str, Any]) -> Figure:
    """Where a compensating controller stops being worth it: its error over a baseline's, per grid point.

    Parameters
    ----------
    comparison : dict
        From :func:`gearctl.sweep.compare_grids`: the baseline's error along the shared key, and per
        controller its error and its ratio to the baseline over (shared key, second key).

    Notes
    -----
    Left: each controller's RMS error against the shared key (a controller with a second key: the line at
    the second key's value nearest 0, the band spanning its other values) with the baseline's. Right, one
    panel per controller with a second key: ``ratio = error / baseline error`` in colour (log scale, blue
    better, red worse) and the contour ``ratio = 1``, where compensating stops paying.
    """
    from matplotlib.colors import LogNorm

    maps = {c: d for c, d in comparison["controllers"].items() if d["y"] is not None}
    fig = Figure(figsize=(5.5 + 4.8 * len(maps), 4.8), layout="constrained")
    axs = fig.subplots(1, 1 + len(maps), squeeze=False)[0]
    x = comparison["x"]
    xs = x / comparison["x_nominal"] if comparison.get("x_nominal") else x
    xlabel = (f"{comparison['x_key']} / nominal" if comparison.get("x_nominal") else comparison["x_key"])
    ax = axs[0]
    ax.plot(xs, comparison["baseline_values"] * 1e6, "k-o", ms=3, label=comparison["baseline"])
    for k, (c, d) in enumerate(comparison["controllers"].items()):
        v = d["values"] * 1e6
        color = f"C{k}"
        if d["y"] is None:
            ax.plot(xs, v, "-o", ms=3, color=color, label=c)
            continue
        j0 = int(np.argmin(np.abs(d["y"])))
        ax.plot(xs, v[:, j0], "-o", ms=3, color=color, label=f"{c}, {d['y_key']} = {d['y'][j0]:.3g}")
        ax.fill_between(xs, np.nanmin(v, axis=1), np.nanmax(v, axis=1), color=color, alpha=0.2,
                        label=f"{c}, {d['y_key']} {d['y'].min():.3g} .. {d['y'].max():.3g}")
    ax.set(xlabel=xlabel, ylabel="RMS error [urad]", yscale="log", title="error against the shared key")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    ratios = (np.concatenate([d["ratio"][np.isfinite(d["ratio"])].ravel() for d in maps.values()]) if maps
              else np.zeros(0))
    span = float(np.max(np.abs(np.log10(ratios)))) if len(ratios) else 1.0
    span = max(span, 0.05)
    for ax, (c, d) in zip(axs[1:], maps.items(), strict=True):
        r = d["ratio"].T
        mesh = ax.pcolormesh(xs, d["y"], r, shading="nearest", cmap="RdBu_r",
                             norm=LogNorm(vmin=10**-span, vmax=10**span))
        fig.colorbar(mesh, ax=ax, label=f"RMS error / {comparison['baseline']}'s")
        if np.nanmin(r) < 1 < np.nanmax(r):
            cs = ax.contour(xs, d["y"], r, levels=[1.0], colors="k", linewidths=1.5)
            ax.clabel(cs, fmt={1.0: "worth it no more"}, fontsize=7)
        ax.set(xlabel=xlabel, ylabel=d["y_key"], title=f"{c} over {comparison['baseline']}")
    return fig


__all__ += ["plot_identification"]


def plot_identification(result: Any, *, ax: Any = None) -> Figure:
    """Measured against re-simulated motion around the gap crossings of an identification.

    Parameters
    ----------
    result : Identification
        From :func:`gearctl.identify.identify`.
    ax : matplotlib Axes, optional
        Draw only the main panel (the relative displacement ``s`` along the line of action, measured dots
        and re-simulated lines, time from each crossing) into it; without it a figure with that panel, the
        motor angle's residual and the estimate of each crossing is made.
    """
    import numpy as np

    rb1, rb2 = result.base_radius
    b = result.backlash
    if ax is None:
        fig = Figure(figsize=(10, 8), layout="constrained")
        axs = fig.subplots(3, 1)
        main = axs[0]
    else:
        fig, axs, main = ax.figure, None, ax
    for j, w in enumerate(result.windows):
        c = f"C{j % 10}"
        tt = (w.t - w.t_switch) * 1e3
        s_sim = rb1 * w.theta1_sim - rb2 * w.theta2_sim
        main.plot(tt, s_sim * 1e6, "-", color=c, lw=1.2)
        if w.theta2 is not None:
            main.plot(tt, (rb1 * w.theta1 - rb2 * w.theta2) * 1e6, ".", color=c, ms=3)
        if axs is not None:
            axs[1].plot(tt, (w.theta1 - w.theta1_sim) / result.gear_ratio * 1e6, "-", color=c, lw=0.8)
    for sgn in (-1, 1):
        main.axhline(sgn * b * 1e6, color="k", ls="--", lw=0.8)
        main.axhspan(sgn * result.backlash_ci[0] * 1e6, sgn * result.backlash_ci[1] * 1e6, color="k", alpha=0.08)
    what = "measured (dots) and re-simulated" if result.encoders == "motor+load" else "re-simulated from the motor"
    main.set(xlabel="time from the gap crossing [ms]", ylabel=r"$s = r_{b1}\theta_1 - r_{b2}\theta_2$ [um]",
             title=f"{result.log}: s {what}, b = {b * 1e6:.4g} um "
                   f"[{result.backlash_ci[0] * 1e6:.4g}, {result.backlash_ci[1] * 1e6:.4g}] ({result.encoders})")
    main.grid(True, alpha=0.3)
    if axs is None:
        return fig
    axs[1].set(xlabel="time from the gap crossing [ms]",
               ylabel="motor angle / N, measured - re-simulated [urad]",
               title=f"residual (RMS {result.rms_residual:.3g} rad in load angle)")
    axs[1].grid(True, alpha=0.3)
    est = np.asarray(result.estimates)
    axs[2].plot(result.estimate_times, est * 1e6, "o", ms=4, label="each crossing" if result.encoders == "motor"
                else "each pair of plateaus")
    axs[2].axhline(b * 1e6, color="k", label="estimate")
    axs[2].axhspan(result.backlash_ci[0] * 1e6, result.backlash_ci[1] * 1e6, color="k", alpha=0.1, label="95 % CI")
    axs[2].axhline(result.nominal["backlash"] * 1e6, color="C3", ls=":", label="model")
    axs[2].set(xlabel="time [s]", ylabel="backlash b [um]")
    axs[2].grid(True, alpha=0.3)
    axs[2].legend(fontsize=8)
    return fig
