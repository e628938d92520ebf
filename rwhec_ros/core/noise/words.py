"""The estimated noise in words: per group, the estimate next to the given noise, and how a
stated noise compares with it (for the summary, the report, /diagnostics and the verdict)."""

from __future__ import annotations

from .estimate import GroupNoise, NoiseEstimate

__all__ = ["group_line", "noise_lines", "stated_comparisons", "times_words", "short_summary",
           "noise_values"]

_GIVEN_WORDS = {"stated": "stated", "reprojection": "from the reprojection",
                "start": "start value"}


def _mm(v: float) -> str:
    return f"{1e3 * v:.3g} mm"


def _deg(v: float) -> str:
    return f"{v:.3g} deg"


def times_words(ratio: float) -> str:
    """``"3.1x too large"`` / ``"2.0x too small"`` for estimated / stated ``ratio`` (std units)."""
    if ratio >= 1.0:
        return f"{ratio:.2g}x too small"
    return f"{1.0 / ratio:.2g}x too large"


def _source(c) -> str:
    return {"estimated": f"{c.dof:.0f} dof", "pooled": f"pooled, {c.dof:.0f} dof",
            "others": "the other groups' estimate", "given": "not estimated"}[c.source]


def group_line(g: GroupNoise, given: str) -> str:
    """``cam_0: sigma 1.8 mm (stated 5 mm; 81 dof), rotation 0.30 deg per axis, kappa 3.6e+04
    (stated 2 deg; 86 dof)``."""
    word = _GIVEN_WORDS.get(given, given)
    return (f"{g.name}: sigma {_mm(g.sigma_m)} ({word} {_mm(g.sigma_given_m)}; "
            f"{_source(g.translation)}), rotation {_deg(g.rotation_std_deg)} per axis, kappa "
            f"{g.kappa:.3g} ({word} {_deg(g.rotation_std_given_deg)}; {_source(g.rotation)})")


def noise_lines(est: NoiseEstimate | None) -> list[str]:
    """Lines for the summary: how the noise was estimated, one line per group, then how a
    stated noise compares (:func:`stated_comparisons`) and the edges left out of the estimate."""
    if est is None:
        return []
    if not est.estimated:
        return ["noise: not estimated (" + ("; ".join(est.notes) or "too little redundancy")
                + "): the given noise weights the pairs"]
    head = (f"noise estimated from the data per {est.grouping.replace('_', '-')} in "
            f"{est.solves} solve{'s' if est.solves > 1 else ''}"
            + ("" if est.converged else " (not converged)")
            + "; the weights, the stds and the certificate use it:")
    left = [f"  not counted in its camera's estimate: edge {e} ({why})"
            for e, why in est.left_out.items()]
    return ([head] + [f"  {group_line(g, est.given)}" for g in est.groups]
            + [f"  {line}" for line in stated_comparisons(est)] + left
            + [f"  note: {n}" for n in est.notes])


def stated_comparisons(est: NoiseEstimate, *, at_least: float = 1.5) -> list[str]:
    """For a stated noise, the groups whose estimate differs from it by ``at_least`` (std
    units) or more: ``"cam_2 translation fits 3.1 mm, stated 100 mm: the stated noise is 32x too
    large; the estimate is used"``."""
    if est.given != "stated":
        return []
    out = []
    for g in est.groups:
        for what, c, fit, stated in (
                ("translation", g.translation, _mm(g.sigma_m), _mm(g.sigma_given_m)),
                ("rotation", g.rotation, _deg(g.rotation_std_deg),
                 _deg(g.rotation_std_given_deg))):
            if c.source not in ("estimated", "pooled"):
                continue
            r = c.ratio
            if r >= at_least or r <= 1.0 / at_least:
                out.append(f"{g.name} {what} fits {fit}, stated {stated}: the stated noise is "
                           f"{times_words(r)}; the estimate is used")
    return out


def short_summary(est: NoiseEstimate | None) -> str:
    """One clause for a verdict's summary: ``noise estimated per camera (3 groups: 1.8-9.9 mm,
    0.30-1.2 deg)``; ``""`` when not estimated."""
    if est is None or not est.estimated:
        return ""
    s = [g.sigma_m for g in est.groups]
    r = [g.rotation_std_deg for g in est.groups]
    n = len(est.groups)

    def span(v, f):
        return f(min(v)) if n == 1 or min(v) == max(v) else f"{f(min(v)).split()[0]}-{f(max(v))}"

    return (f"noise estimated from the data per {est.grouping.replace('_', '-')} ({n} "
            f"group{'s' if n > 1 else ''}: {span(s, _mm)}, {span(r, _deg)} per axis)")


def noise_values(noise) -> list[tuple[str, str]]:
    """``/diagnostics`` key-values of a noise estimate: per group ``noise_<group>_sigma_mm`` and
    ``noise_<group>_rotation_deg`` (per axis), each with its given value beside it, and the
    solves of the last estimate; [] without one."""
    if noise is None or not noise.estimated:
        return []
    out = [("noise_solves", str(noise.solves)), ("noise_given", noise.given)]
    for g in noise.groups:
        out += [(f"noise_{g.name}_sigma_mm", f"{1e3 * g.sigma_m:.3g}"),
                (f"noise_{g.name}_sigma_given_mm", f"{1e3 * g.sigma_given_m:.3g}"),
                (f"noise_{g.name}_rotation_deg", f"{g.rotation_std_deg:.3g}"),
                (f"noise_{g.name}_rotation_given_deg", f"{g.rotation_std_given_deg:.3g}")]
    return out
