"""The per-joint fit table of an identified model, printed by ``identify`` and ``calibrate``."""

from __future__ import annotations

from typing import Any


def format_fit_table(model: Any) -> str:
    """A short per-joint fit table (RMS error in N·m and relative to the torque RMS and range).

    ``model`` is a :class:`impactcli.model.RigidModel`. A joint that stands still in the
    held-back part shows ``still`` instead of relative errors (they would only judge a
    constant); joints predicted worse than zero torque there, and the coupled model's ridge
    penalties, are listed below the table.
    """
    fit = model.fit
    joints = fit["joints"]
    hold = joints.get("holdout")
    cond = fit.get("condition_number")
    cond_txt = "inf" if cond is None else f"{cond:.3g}"
    head = (
        f"{model.kind} model: {len(model.theta)} parameters, condition number "
        f"{cond_txt}" + (" (of its decoupled terms)" if model.kind == "coupled" else "")
        + f", fit on {fit['n_samples_fit']} samples"
        + (f", held-back {fit['n_samples_holdout']} samples" if hold
           else " (nothing held back: log too short or --holdout 0)")
    )
    w = max(5, *(len(j) for j in model.joint_names))
    cols = f"{'joint':<{w}}  {'torque RMS':>10}  {'fit RMS':>8}  {'/RMS':>6}  {'/range':>6}"
    if hold:
        cols += f"  {'held RMS':>8}  {'/RMS':>6}  {'/range':>6}"
    lines = [head, cols + "   [N·m]"]
    worse = []
    for j in model.joint_names:
        f = joints["fit"][j]
        row = (f"{j:<{w}}  {f['torque_rms_nm']:>10.4g}  {f['rms_nm']:>8.4g}  "
               f"{_pct(f.get('rms_rel_torque_rms'), f.get('still'))}  "
               f"{_pct(f.get('rms_rel_range'), f.get('still'))}")
        if hold:
            h = hold[j]
            row += (f"  {h['rms_nm']:>8.4g}  {_pct(h.get('rms_rel_torque_rms'), h.get('still'))}  "
                    f"{_pct(h.get('rms_rel_range'), h.get('still'))}")
            if not h.get("still") and h["torque_rms_nm"] > 0 and \
                    h["rms_nm"] >= h["torque_rms_nm"]:
                worse.append(j)
        lines.append(row)
    if fit.get("still_joints"):
        lines.append(f"still joints (constant torque only): {', '.join(fit['still_joints'])}")
    if hold:
        held_still = [j for j in model.joint_names
                      if hold[j].get("still") and j not in (fit.get("still_joints") or [])]
        if held_still:
            lines.append("still in the held-back part (no relative error there): "
                         + ", ".join(held_still))
    if worse:
        lines.append(f"held back worse than zero torque: {', '.join(worse)}")
    ridge = fit.get("ridge")
    if ridge:
        pen = ", ".join(
            f"{j} {'off' if v.get('lambda') is None else format(v['lambda'], '.2g')}"
            for j, v in ridge["joints"].items())
        lines.append(f"ridge penalty on the cross terms (off: decoupled): {pen}")
    if fit.get("unexcited_parameters"):
        lines.append(f"not excited (fixed at 0): {', '.join(fit['unexcited_parameters'])}")
    from ..model.payload_table import describe

    lines += describe(model)
    return "\n".join(lines)


def _pct(x: float | None, still: bool | None = None) -> str:
    if still:
        return f"{'still':>6}"
    return f"{'—':>6}" if x is None else f"{100 * x:>5.1f}%"
