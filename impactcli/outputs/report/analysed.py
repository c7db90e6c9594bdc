"""What was analysed and with what: the input (file, sha256, clock, sources), the tool,
calibration, model (fit quality, parameters), residual generator per joint, thresholds and
adaptive-filter gain per joint, and the full detector configuration.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import Any

from ... import TOOL_NAME, __version__
from ...detect.tail import SETTLE_S, minutes_text
from .common import LogSection, e, epoch_text, f, g, json_pre, kv_table


def settings_table(cfg: dict[str, Any]) -> str:
    """Every config value, one row per section: ``key=value`` with nested keys dotted and
    values as compact JSON (the JSON report holds the same mapping)."""
    def flat(d: dict[str, Any], prefix: str = "") -> list[tuple[str, Any]]:
        out: list[tuple[str, Any]] = []
        for k in sorted(d):
            v = d[k]
            if isinstance(v, dict) and v:
                out += flat(v, f"{prefix}{k}.")
            else:
                out.append((f"{prefix}{k}", v))
        return out

    rows = []
    for section in sorted(cfg):
        v = cfg[section]
        if isinstance(v, dict):
            items = flat(v)
            text = "; ".join(
                f"{k}={json.dumps(x, sort_keys=True, ensure_ascii=False)}" for k, x in items)
            rows.append((section, f'<span class="mono small">{e(text or "{}")}</span>'))
        else:
            rows.append((section, f'<span class="mono small">{e(json.dumps(v))}</span>'))
    return kv_table(rows)




def generator_cell(replay: dict[str, Any]) -> str:
    """Which residual generator each joint used and why (timeline 2.0), or the one name a
    1.0 timeline records."""
    per = replay.get("generator") or {}
    if not per:
        return e(replay.get("residual_generator", "—"))
    rows = "".join(
        f"<li><b>{e(j)}</b>: {e(g.get('generator'))} — {e(g.get('reason'))}"
        + (f" (<code>{e(g['residual'])}</code>)" if g.get("residual") else "") + "</li>"
        for j, g in per.items())
    return f'<ul style="margin:0;padding-left:1.2em">{rows}</ul>'


def fit_table(fit: dict[str, Any], joints: Sequence[str]) -> str:
    """The model's fit statistics (impactcli.model.identification layout: per joint RMS of the
    torque error on the fitted and the held-back part); any other layout generically."""
    per = fit.get("joints") if isinstance(fit.get("joints"), dict) else None
    if not per or not isinstance(per.get("fit"), dict):
        return generic_fit_table(fit, joints)
    fitj = per.get("fit") or {}
    hold = per.get("holdout") or {}
    robust = fit.get("robust") or {}
    down = robust.get("downweighted_fraction") or {}
    cols = [("fit RMS error [N·m]", lambda j: (fitj.get(j) or {}).get("rms_nm")),
            ("… / torque RMS", lambda j: (fitj.get(j) or {}).get("rms_rel_torque_rms")),
            ("hold-out RMS error [N·m]", lambda j: (hold.get(j) or {}).get("rms_nm")),
            ("… / torque RMS", lambda j: (hold.get(j) or {}).get("rms_rel_torque_rms")),
            ("torque RMS [N·m]", lambda j: (fitj.get(j) or {}).get("torque_rms_nm")),
            ("down-weighted fraction", down.get)]
    head = "".join(f'<th class="num">{e(c)}</th>' for c, _ in cols)
    body = "".join(
        f"<tr><th>{e(j)}</th>" + "".join(f'<td class="num">{g(fn(j))}</td>' for _, fn in cols)
        + "</tr>" for j in joints)
    unexc = fit.get("unexcited_parameters") or []
    rows = [("method", e(fit.get("method", "—"))),
            ("samples fitted / held out", f"{f(fit.get('n_samples_fit'))} / "
                                          f"{f(fit.get('n_samples_holdout'))}"
             + ("" if hold else ' <span class="warn">(not validated on held-out data)</span>')),
            ("condition number", g(fit.get("condition_number"))),
            ("unexcited parameters (fixed at 0)",
             e(", ".join(map(str, unexc))) if unexc else "none")]
    opts = fit.get("options")
    if isinstance(opts, dict) and opts:
        rows.append(("identification options", '<span class="small">' + e(", ".join(
            f"{k}={v}" for k, v in sorted(opts.items()))) + "</span>"))
    return (f'<div class="wide"><table><thead><tr><th>joint</th>{head}</tr></thead>{body}</table>'
            f"</div>{kv_table(rows)}")


def params_table(params: list[dict[str, Any]], joints: Sequence[str]) -> str:
    """Parameters ``<joint>.<name>`` as a joints × names matrix; other names listed after."""
    matrix: dict[str, dict[str, Any]] = {}
    names: list[str] = []
    rest: list[dict[str, Any]] = []
    for q in params:
        joint, _, name = str(q.get("name", "")).partition(".")
        if joint in joints and name:
            matrix.setdefault(joint, {})[name] = q.get("value")
            if name not in names:
                names.append(name)
        else:
            rest.append(q)
    out = ""
    if matrix:
        head = "".join(f'<th class="num">{e(n)}</th>' for n in names)
        body = "".join(f"<tr><th>{e(j)}</th>" + "".join(
            f'<td class="num">{g(matrix.get(j, {}).get(n))}</td>' for n in names) + "</tr>"
            for j in joints if j in matrix)
        out += (f'<div class="wide"><table><thead><tr><th>joint</th>{head}</tr></thead>'
                f"{body}</table></div>")
    if rest:
        out += ('<table><thead><tr><th>parameter</th><th class="num">value</th></tr></thead>'
                + "".join(f"<tr><td><code>{e(q.get('name'))}</code></td>"
                          f'<td class="num">{g(q.get("value"))}</td></tr>' for q in rest)
                + "</table>")
    return out + '<p class="small muted">SI units: kg·m², kg·m, N·m·s/rad, N·m.</p>'


def generic_fit_table(fit: dict[str, Any], joints: Sequence[str]) -> str:
    """The model's fit statistics: per-joint quantities as columns, scalars as rows."""
    if not fit:
        return '<p class="muted">The model records no fit statistics.</p>'
    per_joint: dict[str, dict[str, Any]] = {}
    scalars: list[tuple[str, Any]] = []
    other: dict[str, Any] = {}
    for k, v in fit.items():
        if isinstance(v, dict) and v and set(v) <= set(joints):
            per_joint[k] = v
        elif (
            isinstance(v, list)
            and len(v) == len(joints)
            and all(isinstance(x, int | float) for x in v)
        ):
            per_joint[k] = dict(zip(joints, v, strict=True))
        elif isinstance(v, int | float | str | bool) or v is None:
            scalars.append((k, v))
        elif isinstance(v, list) and len(v) > 12:
            scalars.append((k, f"{len(v)} values (in the JSON report)"))
        else:
            other[k] = v
    out = []
    if per_joint:
        head = "".join(f'<th class="num">{e(k)}</th>' for k in per_joint)
        body = "".join(
            f"<tr><th>{e(j)}</th>"
            + "".join(f'<td class="num">{g(per_joint[k].get(j))}</td>' for k in per_joint)
            + "</tr>"
            for j in joints
        )
        out.append(f"<table><tr><th>joint</th>{head}</tr>{body}</table>")
    if scalars:
        out.append(kv_table([(k, g(v)) for k, v in scalars]))
    if other:
        out.append(json_pre(other))
    return "".join(out)




def analysed_html(sec: LogSection) -> str:
    """The input, as read."""
    inp = sec["input"]
    return "<h3>What was analysed</h3>" + kv_table([
        ("file", f"<code>{e(inp['path'])}</code>"),
        ("sha256", f'<code class="hash">{e(inp["sha256"])}</code>'),
        ("format", e(inp.get("format", "—"))),
        ("samples", f(inp.get("n_samples"))),
        ("duration", f"{inp['duration_s']:.3f} s"),
        ("sample rate", f"{inp['sample_rate_hz']:.2f} Hz (median)"),
        ("joints", e(", ".join(inp["joints"]))),
        ("first sample (t0_ns)",
         f"{inp['t0_ns']} ns on the log's own clock{epoch_text(inp['t0_ns'])}; "
         "times in this report are seconds since this sample"),
        ("torque source", e(inp["torque_source"])),
        ("time source", e(inp["time_source"])),
        ("read options",
         f"<code>{e(json.dumps(inp.get('read_options') or {}, sort_keys=True))}</code>"),
        ("repairs", e("; ".join(inp.get("repairs") or []) or "none")),
    ])


def with_what_html(sec: LogSection) -> str:
    """The tool, calibration, model, generators, thresholds and the full configuration."""
    joints = list(sec["input"]["joints"])
    model = sec["model"] or {"source": "none", "sha256": None, "model": {}}
    cfg = sec["config"] or {}
    calib = cfg.get("calibration") or {}
    replay = sec["replay"]
    calibrated = ('<span class="good">yes</span>' if sec["calibrated"]
                  else '<span class="bad">no — uncalibrated run</span>')
    logs = "<br>".join(f'<code>{e(lg.get("path"))}</code> <code class="hash small">'
                       f'{e(lg.get("sha256"))}</code>' for lg in calib.get("logs") or []) or "—"
    ref = e(replay["reference_source"]) + (
        "" if replay["reference_source"] == "reference"
        else ' <span class="warn">(no logged reference)</span>')
    p = ["<h3>With what</h3>", kv_table([
        ("tool", f"{e(TOOL_NAME)} {e(__version__)}"),
        ("calibrated thresholds", calibrated),
        ("threshold rule", threshold_rule_cell(calib)),
        ("margin rule", e(calib.get("margin_rule") or "—")),
        ("calibrated on", logs),
        ("model", f"{e(model['model'].get('kind', '?'))}, source: {e(model['source'])}"
         if model["model"] else "none (every joint read the controller's channels)"),
        ("model sha256", f'<code class="hash">{e(model["sha256"] or "—")}</code>'),
        ("thresholds belong to model",
         f'<code class="hash">{e(calib.get("model_sha256") or "—")}</code>'),
        ("online-equivalent replay", f(replay["online_equivalent"])),
        ("reference", ref),
        ("threshold inputs", e(replay.get("threshold_inputs") or "—")),
        ("torque filtered like the estimate", f(replay["torque_filtered"])),
        ("residual generator", generator_cell(replay)),
        ("warm-up end", f"{sec['warmup_end_s']:.3f} s (latest over joints)"),
    ])]
    if model["model"]:
        p.append("<h4>Model fit quality</h4>" + fit_table(model["model"].get("fit") or {}, joints))
    params = model["model"].get("parameters")
    if isinstance(params, list) and params:
        p.append("<h4>Model parameters</h4>" + params_table(params, joints))
    p.append("<h4>Thresholds and adaptive filter gain per joint</h4>"
             + thresholds_table(sec, joints))
    rate = calib.get("false_alarm_rate")
    if isinstance(rate, dict):
        p.append(("<h4>Thresholds for a false-alarm rate</h4>" if "per_hour" in rate else
                  "<h4>The thresholds' predicted false-alarm rate</h4>") + rate_html(rate))
    env = calib.get("motion_envelope")
    if isinstance(env, dict):
        p.append("<h4>The calibration's motion envelope</h4>" + envelope_html(env))
    p.append("<h4>Full detector configuration</h4>")
    p.append(settings_table({k: v for k, v in cfg.items() if k != "model"}))
    if cfg.get("model") is not None:
        p.append('<p class="small muted">The config also embeds its model (sha256 above); '
                 "it is in the JSON report.</p>")
    return "".join(p)


def threshold_rule_cell(calib: dict[str, Any]) -> str:
    """How v_stat and vL were set: for a stated false-alarm rate (R, predicted rate and
    bound, free minutes, whether they support R) or by the margin rule (with the rate its
    thresholds are predicted to give, when recorded)."""
    rate = calib.get("false_alarm_rate")
    if not isinstance(rate, dict):
        rule = calib.get("threshold_rule") or calib.get("margin_rule")
        return e(rule or "—") + (" (no stated false-alarm rate)" if rule else "")
    conf = rate.get("confidence")
    how = (f"for {g(rate.get('per_hour'))} false alarm(s) per hour" if "per_hour" in rate
           else f"{calib.get('margin_rule') or calib.get('threshold_rule') or '—'}, no rate "
                "asked; the rate its thresholds give")
    txt = (f"{how} (incidents after warm-up, "
           f"all joints together): predicted {g(rate.get('predicted_per_hour'))} per hour, "
           f"upper bound {g(rate.get('upper_per_hour'))} at "
           f"{'—' if conf is None else format(100 * conf, '.0f')} % confidence, on "
           f"{minutes_text(float(rate.get('free_minutes') or 0.0))} min of free motion; v0 by "
           f"{calib.get('margin_rule') or '—'}")
    out = e(txt)
    if rate.get("statement"):
        cls = "warn" if rate.get("supported") is False else "muted"
        out += f'<br><span class="{cls} small">{e(rate["statement"])}</span>'
    return out


def rate_html(rate: dict[str, Any]) -> str:
    """Per detector and joint: threshold, tail fit, predicted rate and bound; notes;
    leave-one-log-out rows (predicted against observed)."""
    rows = []
    floor = " (log-start floor)" if "per_hour" in rate else " (below log-start floor)"
    for det, per in (rate.get("channels") or {}).items():
        for j, c in per.items():
            tag = (" (widened)" if c.get("widened") else
                   floor if c.get("log_start_floor") else "")
            shape = ("exponential" if c.get("shape") == "exponential"
                     else f"GPD ξ {g(c.get('xi'))}" if c.get("shape") else "—")
            rows.append(
                f"<tr><th>{e(j)}</th><td>{e(det)}</td><td class=\"num\">{g(c.get('threshold'))}"
                f"{e(tag)}</td><td class=\"num\">{g(c.get('free_max'))}</td>"
                f"<td>{e(shape)}, σ {g(c.get('sigma'))}, u {g(c.get('level'))}, "
                f"{f(c.get('clusters'))} clusters</td>"
                f"<td class=\"num\">{g(c.get('predicted_per_hour'))}</td>"
                f"<td class=\"num\">{g(c.get('upper_per_hour'))}</td></tr>")
    out = ""
    if rows:
        out += ('<div class="wide"><table><tr><th>joint</th><th>detector</th>'
                '<th class="num">threshold [N·m]</th><th class="num">free max [N·m]</th>'
                '<th>tail fit</th><th class="num">predicted [1/h]</th>'
                '<th class="num">upper bound [1/h]</th></tr>' + "".join(rows)
                + "</table></div>")
    notes = rate.get("notes") or []
    if notes:
        out += '<ul class="small">' + "".join(f"<li>{e(n)}</li>" for n in notes) + "</ul>"
    lolo = rate.get("leave_one_log_out") or []
    if lolo:
        body = "".join(
            f"<tr><td><code>{e(r.get('log'))}</code></td><td class=\"num\">"
            f"{f(r.get('minutes'), 2)}</td><td class=\"num\">{g(r.get('per_hour'))}</td>"
            f"<td class=\"num\">{f(r.get('observed'))}</td>"
            f"<td class=\"num\">{g(r.get('predicted_per_hour'))}</td>"
            f"<td class=\"num\">{g(r.get('upper_per_hour'))}</td></tr>" for r in lolo)
        out += ('<p class="small">Leave-one-log-out: each free log against the thresholds of '
                "the others, at rates its minutes can show (a log above its bound moves "
                "unlike the others); its minutes are the whole log after warm-up, where the "
                f"tail fits leave out each log's first {SETTLE_S:g} s, held to the log-start "
                "floor.</p><div class=\"wide\"><table><tr><th>log left out</th>"
                '<th class="num">min</th><th class="num">R [1/h]</th>'
                '<th class="num">incidents seen</th><th class="num">predicted [1/h]</th>'
                '<th class="num">upper bound [1/h]</th></tr>' + body + "</table></div>")
    return out or '<p class="muted">No fit recorded.</p>'


def envelope_html(env: dict[str, Any]) -> str:
    """Per joint the ranges of velocity, acceleration and position calibrated on."""
    src = {"position_ref": "the logs' reference", "position": "the measured position"}
    rows = "".join(
        f"<tr><th>{e(j)}</th>" + "".join(
            f'<td class="num">{g((q.get(k) or [None, None])[0])} … '
            f'{g((q.get(k) or [None, None])[1])}</td>'
            for k in ("velocity", "acceleration", "position")) + "</tr>"
        for j, q in (env.get("joints") or {}).items())
    source = str(env.get("source"))
    return (f'<p class="small">Of {e(src.get(source, source))}, '
            f"{f(env.get('samples'))} samples after warm-up: a stated rate holds for motion "
            "inside these ranges.</p>"
            '<table><tr><th>joint</th><th class="num">velocity [rad/s]</th>'
            '<th class="num">acceleration [rad/s²]</th><th class="num">position [rad]</th>'
            f"</tr>{rows}</table>")


def thresholds_table(sec: LogSection, joints: Sequence[str]) -> str:
    """v_stat, v0, vL, warm-up end and |G| per joint."""
    fg = sec.get("filter_gain") or {}
    freqs = list(fg.get("frequencies_hz") or [])
    gains = fg.get("gain") or {}
    head = ('<tr><th>joint</th><th class="num">v_stat [N·m]</th><th class="num">v0 [N·m]</th>'
            '<th class="num">vL [N·m]</th><th class="num">warm-up end [s]</th>'
            + "".join(f'<th class="num">|G| at {fr:.3g} Hz</th>' for fr in freqs) + "</tr>")
    rows = []
    for j in joints:
        th = sec["thresholds"].get(j, {})
        rows.append(
            f"<tr><th>{e(j)}</th>"
            + "".join(f'<td class="num">{g(th.get(x))}</td>' for x in ("v_stat", "v0", "vL"))
            + f'<td class="num">{f((sec.get("warmup_per_joint_s") or {}).get(j))}</td>'
            + "".join(f'<td class="num">{g(x)}</td>' for x in gains.get(j) or [])
            + "</tr>")
    return f'<div class="wide"><table>{head}{"".join(rows)}</table></div>'
