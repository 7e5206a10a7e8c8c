"""The tables and verdicts of ``livedic bench live``'s pipeline cases: one line per row, PASS/FAIL per target."""

import math

from livedic.dic.search import DEFAULT_SEARCH

from livedic.bench.live.cases import (METHODS, TARGET_FPS, TARGET_METHOD, TARGET_P99_MS, TARGET_POINTS,
                                      TARGET_STRAIN_MS, TARGET_STRAIN_OUT_P99_MS)


def number_text(value, fmt, missing="n/a"):
    """``value`` formatted with ``fmt``; ``missing`` for None or a non-finite float."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return missing
    return format(value, fmt)


def case_label(row):
    """The method of ``row``, with what differs from the standard case (search, no recording, unpaced)."""
    label = row["subpixel"]
    notes = []
    if row.get("search", DEFAULT_SEARCH) != DEFAULT_SEARCH:
        notes.append(f"search {row['search']}")
    if not row["record"]:
        notes.append("no-record")
    if not row["paced"]:
        notes.append("unpaced")
    return label + (f" ({', '.join(notes)})" if notes else "")


HEADER = (f"{'points':>6s} {'method':34s} {'fps in':>6s} {'fps out':>7s} {'tracked':>9s} {'drops':>5s} "
          f"{'lat p50':>8s} {'lat p99':>8s} {'trk p50':>8s} {'trk p99':>8s} {'POI/s':>9s} {'err RMS':>8s}")


def format_row(row):
    s = row["summary"]
    if row["error"] and not s:
        return f"{row['points_wanted']:>6d} {case_label(row):34s} failed: {row['error']}"
    paced = row["paced"]

    def ms(key, meaningful=True):
        value = s.get(key)
        if not meaningful:
            return f"{'n/a*':>8s}"
        return f"{number_text(value, '6.1f')}ms" if number_text(value, '6.1f') != "n/a" else f"{'n/a':>8s}"

    return (f"{s.get('points', row['points_wanted']):>6d} {case_label(row):34s} "
            f"{number_text(row['fps_offered'], '6.0f') if paced else 'max':>6s} {number_text(s.get('fps'), '7.1f'):>7s} "
            f"{s.get('frames', 0):>4d}/{s.get('acquired', 0):<4d} {s.get('dropped', 0):>5d} "
            f"{ms('latency_p50_ms', paced)} {ms('latency_p99_ms', paced)} "
            f"{ms('processing_p50_ms')} {ms('processing_p99_ms')} "
            f"{number_text(s.get('poi_per_s'), '9,.0f'):>9s} {number_text(s.get('error_rms_px'), '8.4f'):>8s}")


def judge_target(row, *, quick=False):
    """(passed: bool, one line) for the issue-3 target on ``row`` (1,000 points, IC-GN, recorded, paced)."""
    variant = "" if row is None or row.get("search", DEFAULT_SEARCH) == DEFAULT_SEARCH else f" --search {row['search']}"
    if row is None or not row["summary"]:
        why = row["error"] if row else "the case did not run"
        return False, (f"FAIL  target 1,000 points IC-GN{variant} >= {TARGET_FPS:g} fps, p99 <= {TARGET_P99_MS:g} ms, "
                       f"no drops: {why}")
    s = row["summary"]
    offered = row["fps_offered"] or 0.0
    dropped = int(s.get("dropped") or 0)
    every_frame = s.get("frames") == s.get("acquired") and dropped == 0
    p99 = s.get("latency_p99_ms")
    checks = [
        (offered >= TARGET_FPS, f"offered {offered:g} fps {'>=' if offered >= TARGET_FPS else '<'} {TARGET_FPS:g}"),
        (every_frame, f"{s.get('frames')}/{s.get('acquired')} frames tracked, {dropped} dropped "
                      f"(fps out {number_text(s.get('fps'), '.1f')}: the reference set-up, {number_text(s.get('setup_ms'), '.0f')} ms, "
                      "and the last frame's latency are in its denominator)"),
        (p99 is not None and math.isfinite(p99) and p99 <= TARGET_P99_MS,
         f"latency p99 {number_text(p99, '.1f')} ms {'<=' if p99 is not None and p99 <= TARGET_P99_MS else '>'} "
         f"{TARGET_P99_MS:g} ms"),
    ]
    passed = all(ok for ok, _ in checks)
    where = f"{row['size']}x{row['size']}, {s.get('points')} points, {row['search']} + IC-GN, recording on"
    note = "  [quick mode: not the 1 MP configuration of the target]" if quick else ""
    return passed, (f"{'PASS' if passed else 'FAIL'}  target 1,000 points IC-GN{variant} >= {TARGET_FPS:g} fps, "
                    f"p99 <= {TARGET_P99_MS:g} ms, no drops ({where}): "
                    + "; ".join(("ok " if ok else "NOT ") + text for ok, text in checks) + note)


def strain_cost_line(row):
    """One line: the strain stage's cost per frame in ``row``'s session, in ms and against its tracking time."""
    s = row["summary"]
    strain = s.get("strain") if s else None
    if not strain:
        return f"  {row['points_wanted']:>6d} {case_label(row):34s} n/a ({row['error'] or 'no strain in the summary'})"
    p50, p99, track = strain.get("strain_ms_p50"), strain.get("strain_ms_p99"), s.get("processing_p50_ms")
    share = f"{100 * p50 / track:5.1f} %" if p50 is not None and track else "  n/a"
    names = ", ".join(strain.get("extensometers") or {}) or "none"
    return (f"  {s.get('points', row['points_wanted']):>6d} {case_label(row):34s} p50 {number_text(p50, '6.3f')} ms, "
            f"p99 {number_text(p99, '6.3f')} ms; {share} of tracking (p50 {number_text(track, '.1f')} ms); extensometers {names}")


def judge_strain_cost(row, *, quick=False):
    """(passed: bool, one line) for the issue-11 target on ``row`` (1,000 points IC-GN): strain <= 2 ms per frame."""
    strain = (row or {}).get("summary", {}).get("strain") if row else None
    if not strain or strain.get("strain_ms_p50") is None:
        why = (row or {}).get("error") or "no strain cost in the summary"
        return False, f"FAIL  target strain + two extensometers <= {TARGET_STRAIN_MS:g} ms per frame at 1,000 points: {why}"
    s = row["summary"]
    p50, p99 = strain["strain_ms_p50"], strain["strain_ms_p99"]
    track = s.get("processing_p50_ms")
    passed = p50 <= TARGET_STRAIN_MS
    names = list(strain.get("extensometers") or {})
    note = "  [quick mode: not the 1 MP configuration of the target]" if quick else ""
    return passed, (f"{'PASS' if passed else 'FAIL'}  target strain + two extensometers <= {TARGET_STRAIN_MS:g} ms per "
                    f"frame at 1,000 points: p50 {p50:.3f} ms (p99 {number_text(p99, '.3f')} ms, "
                    f"{'also' if p99 is not None and p99 <= TARGET_STRAIN_MS else 'NOT'} <= {TARGET_STRAIN_MS:g}), "
                    f"{number_text(100 * p50 / track if track else None, '.1f')} % of the tracking time (p50 "
                    f"{number_text(track, '.1f')} ms) in the same session ({row['size']}x{row['size']}, {s.get('points')} "
                    f"points, IC-GN, window {strain.get('strain_window')}, VSG {number_text(strain.get('vsg_px'), 'g')} px, "
                    f"extensometers {', '.join(names) or 'none'}, axial {row['gauge_length']:g} px){note}")


def strain_out_line(row):
    """One line: ``row``'s strain-out latency (result -> sent, -> in the receiving socket, -> read by a thread)."""
    out = row.get("strain_out")
    if not out:
        return f"  {row['points_wanted']:>6d} {case_label(row):34s} n/a ({row['error'] or 'nothing published'})"
    s = row["summary"]

    def pair(key):
        return f"p50 {number_text(out[key + '_p50_ms'], '.2f')} ms, p99 {number_text(out[key + '_p99_ms'], '.2f')} ms"
    failed = f", {out['failed']} NOT sent" if out["failed"] else ""
    arrival = (f"in the socket {pair('arrival')}; " if out["arrival_p99_ms"] is not None
               else "in the socket n/a (no kernel timestamps); ")
    return (f"  {s.get('points', row['points_wanted']):>6d} {case_label(row):34s} {out['sent']}/{out['frames']} sent"
            f"{failed}, {out['received']} received; result -> sent {pair('sent')} (before the publisher "
            f"{pair('upstream')}; in it {pair('stage')}); {arrival}read by a thread {pair('read')}")


def judge_strain_out(row, *, quick=False):
    """(passed: bool, one line) for the issue-13 target on ``row``: strain-out latency p99 <= 5 ms at 50 fps."""
    title = (f"target strain-out latency p99 <= {TARGET_STRAIN_OUT_P99_MS:g} ms at {TARGET_FPS:g} fps on loopback "
             f"(1,000 points IC-GN)")
    out = (row or {}).get("strain_out")
    if not out or not out.get("sent"):
        why = (row or {}).get("error") or "nothing was published"
        return False, f"FAIL  {title}: {why}"
    if out["arrival_p99_ms"] is not None:
        judged, p50, where = out["arrival_p99_ms"], out["arrival_p50_ms"], "in the receiving socket (kernel timestamp)"
    else:
        judged, p50, where = out["read_p99_ms"], out["read_p50_ms"], "read by a thread of this process"
    offered = row["fps_offered"] or 0.0
    passed = judged is not None and judged <= TARGET_STRAIN_OUT_P99_MS and offered >= TARGET_FPS
    all_sent = out["received"] == out["sent"] == out["frames"]
    note = "  [quick mode: not the 1 MP configuration of the target]" if quick else ""
    return passed, (f"{'PASS' if passed else 'FAIL'}  {title}: result -> {where} p99 {number_text(judged, '.2f')} ms "
                    f"(p50 {number_text(p50, '.2f')} ms); result -> send returned p99 {number_text(out['sent_p99_ms'], '.2f')} ms; "
                    f"{out['received']} datagrams for {out['frames']} tracked frames"
                    f"{'' if all_sent else ' (NOT one per frame)'}; offered {offered:g} fps "
                    f"({row['size']}x{row['size']}, {row['summary'].get('points')} points, {row['search']} + IC-GN, "
                    f"recording on){note}")


def _fit_cost(rows):
    """Least-squares tracking p50 = a + b * points over ``rows``: (a ms, b us/point) or None."""
    pts = [(r["summary"].get("points"), r["summary"].get("processing_p50_ms")) for r in rows if r["summary"]]
    pts = [(n, ms) for n, ms in pts if n and ms is not None and math.isfinite(ms)]
    if len({n for n, _ in pts}) < 2:
        return None
    import numpy as np
    n = np.array([p[0] for p in pts], dtype=float)
    ms = np.array([p[1] for p in pts], dtype=float)
    b, a = np.polyfit(n, ms, 1)
    return float(a), float(b) * 1e3


def explain_limits(rows, fps):
    """Lines saying what bounds the rate and the latency (from the summaries of this run)."""
    lines = []
    budget = 1e3 / fps if fps else float("nan")
    by_key = {(r["points_wanted"], r["subpixel"], r["record"], r["paced"]): r for r in rows
              if r["search"] == DEFAULT_SEARCH}
    for method in METHODS:
        paced_rows = [r for r in rows if r["subpixel"] == method and r["record"] and r["paced"]
                      and r["search"] == DEFAULT_SEARCH]
        fit = _fit_cost(paced_rows)
        if fit is not None:
            a, b = fit
            lines.append(f"  {method}: tracking p50 ~ {a:.1f} ms per frame + {b:.1f} us per point "
                         f"(fit over {len(paced_rows)} point counts{'; noisy: negative intercept' if a < 0 else ''}) "
                         f"-> 1,000 points ~ {a + b:.1f} ms, budget at {fps:g} fps is {budget:.1f} ms")
    target = by_key.get((TARGET_POINTS, TARGET_METHOD, True, True))
    if target and target["summary"]:
        s = target["summary"]
        p50 = s.get("processing_p50_ms")
        if p50:
            lines.append(f"  1,000 points IC-GN: tracking p50 {p50:.1f} ms / p99 {number_text(s.get('processing_p99_ms'), '.1f')} ms"
                         f" per frame -> at most ~{1e3 / p50:.0f} fps from tracking alone; "
                         f"frame delivery delay p99 {number_text(s.get('delivery_delay_p99_ms'), '.1f')} ms "
                         "(capture -> the acquisition thread has it; it grows when that thread waits for the GIL)")
            p99 = s.get("latency_p99_ms")
            if p99 is not None and p50 > 1e3 / (target["fps_offered"] or TARGET_FPS):
                lines.append(f"  tracking is slower than the frame period, so frames queue up: latency "
                             f"(p99 {p99:.1f} ms) is mostly queue wait, and once the queue is full it drops frames")
    norec = by_key.get((TARGET_POINTS, TARGET_METHOD, False, True))
    if target and norec and target["summary"] and norec["summary"]:
        t, n = target["summary"], norec["summary"]
        lines.append(f"  recording: tracking p50 {number_text(t.get('processing_p50_ms'), '.1f')} ms with it vs "
                     f"{number_text(n.get('processing_p50_ms'), '.1f')} ms without; latency p99 "
                     f"{number_text(t.get('latency_p99_ms'), '.1f')} vs {number_text(n.get('latency_p99_ms'), '.1f')} ms; "
                     f"drops {t.get('dropped')} vs {n.get('dropped')}")
    unseeded = next((r for r in rows if r["search"] == "none" and r["points_wanted"] == TARGET_POINTS
                     and r["subpixel"] == TARGET_METHOD and r["record"] and r["paced"]), None)
    if target and unseeded and target["summary"] and unseeded["summary"]:
        t, n = target["summary"], unseeded["summary"]
        if t.get("processing_p50_ms") is not None and n.get("processing_p50_ms") is not None:
            lines.append(f"  seeding search: improved-wso r2 (run only for points IC-GN from the previous result leaves "
                         f"doubtful) + IC-GN takes {t['processing_p50_ms']:.1f} ms per frame (p50), IC-GN from the "
                         f"previous result alone (--search none) {n['processing_p50_ms']:.1f} ms: the integer search "
                         f"costs {t['processing_p50_ms'] - n['processing_p50_ms']:.1f} ms; error "
                         f"RMS {number_text(t.get('error_rms_px'), '.4f')} vs {number_text(n.get('error_rms_px'), '.4f')} px, "
                         f"re-found points {t.get('refound')} vs {n.get('refound')}")
    unpaced = by_key.get((TARGET_POINTS, TARGET_METHOD, True, False))
    if unpaced and unpaced["summary"]:
        lines.append(f"  highest sustained rate, 1,000 points IC-GN with recording (unpaced source, blocking queue): "
                     f"{number_text(unpaced['summary'].get('fps'), '.1f')} fps")
    return lines
