"""Scripted input: a JSON list of per-frame actions that drives the real viewer loop.

The same entry points as the mouse, keyboard and panel are used (a scripted ``orbit`` is a
left-button drag of that many pixels), so a script tests the viewer as a user drives it. Used by
the tests (under Xvfb) and for reproducible screenshots and videos of a session.

    {
      "actions": [
        {"frame": 0, "orbit": [120, 0]},
        {"frame": 1, "screenshot": "orbit.png"},
        {"frame": 2, "set": {"technique": "lambert"}},
        {"frame": 3, "set": {"profile": "physical", "melanin": 0.3}, "screenshot": "dark.png"},
        {"frame": 4, "resources": true}
      ],
      "quit_after": 5,
      "report": "session.json"
    }

Actions run before frame ``frame`` is drawn, except ``screenshot`` (the tone-mapped render, as
``dermis render`` writes it), ``window_screenshot`` (the window with its panel) and
``resources`` (record the live GPU object counts), which run after it. Keys of an action:
orbit, pan, light_drag ([dx, dy] pixels), zoom (wheel steps), set (ViewerParams fields),
preset (a profile preset, moving the sliders), reset_camera, screenshot, window_screenshot,
resources, quit. ``quit_after`` ends the session after that many frames; ``report`` writes the
frame times, resource counts and screenshots as JSON. ``scales`` (optional): the reduced frames' output
scales (each one of dermis.viewer.progressive.SCALE_STEPS), frame f's taken from scales[f % len(scales)]
instead of adapting to the measured frame time: a session whose frames do not depend on the machine's
speed or load (the GPU-object test compares cycles of frames, tests/test_viewer.py). Relative paths are relative to the
script's folder. A profile change waits for its computation so the next image shows it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from dermis.errors import DermisError

BEFORE = ("orbit", "pan", "light_drag", "zoom", "set", "preset", "reset_camera")
AFTER = ("screenshot", "window_screenshot", "resources", "quit")
MAX_FRAMES = 1_000_000


@dataclass
class Script:
    actions: dict = field(default_factory=dict)  # frame -> list of action dicts, in file order
    quit_after: int | None = None
    report: Path | None = None
    source: str = "<script>"
    scales: tuple = ()  # the reduced frames' output scales by frame number (empty: adapted to the frame time)

    @classmethod
    def from_dict(cls, data: dict, source: str = "<script>", base_dir: Path | None = None) -> "Script":
        if not isinstance(data, dict):
            raise DermisError(f"{source}: a script is a JSON object with 'actions'")
        unknown = set(data) - {"actions", "quit_after", "report", "scales"}
        if unknown:
            raise DermisError(f"{source}: unknown key '{sorted(unknown)[0]}' (known: actions, quit_after, report, scales)")
        base = Path(base_dir) if base_dir is not None else Path(".")
        actions: dict[int, list] = {}
        raw = data.get("actions", [])
        if not isinstance(raw, list):
            raise DermisError(f"{source}: 'actions' must be a list")
        for i, a in enumerate(raw):
            where = f"{source}: action {i}"
            if not isinstance(a, dict) or "frame" not in a:
                raise DermisError(f"{where}: each action is an object with a 'frame'")
            frame = a["frame"]
            if isinstance(frame, bool) or not isinstance(frame, int) or not 0 <= frame < MAX_FRAMES:
                raise DermisError(f"{where}: 'frame' must be an integer >= 0, got {frame!r}")
            bad = set(a) - set(BEFORE) - set(AFTER) - {"frame"}
            if bad:
                raise DermisError(f"{where}: unknown action '{sorted(bad)[0]}' (known: {', '.join(BEFORE + AFTER)})")
            a = dict(a)
            for k in ("orbit", "pan", "light_drag"):
                if k in a:
                    v = a[k]
                    if not (isinstance(v, list) and len(v) == 2 and all(isinstance(x, (int, float)) for x in v)):
                        raise DermisError(f"{where}: '{k}' must be [dx, dy] in pixels")
            if "zoom" in a and not isinstance(a["zoom"], (int, float)):
                raise DermisError(f"{where}: 'zoom' must be a number of wheel steps")
            if "set" in a and not isinstance(a["set"], dict):
                raise DermisError(f"{where}: 'set' must be an object of viewer parameters")
            for k in ("screenshot", "window_screenshot"):
                if k in a:
                    if not isinstance(a[k], str) or not a[k]:
                        raise DermisError(f"{where}: '{k}' must be a file path")
                    a[k] = base / a[k]
            actions.setdefault(frame, []).append(a)
        quit_after = data.get("quit_after")
        if quit_after is not None and (isinstance(quit_after, bool) or not isinstance(quit_after, int) or quit_after < 1):
            raise DermisError(f"{source}: 'quit_after' must be an integer >= 1")
        report = data.get("report")
        if report is not None and not isinstance(report, str):
            raise DermisError(f"{source}: 'report' must be a file path")
        from dermis.viewer.progressive import SCALE_STEPS

        scales = data.get("scales", [])
        if not isinstance(scales, list) or any(isinstance(x, bool) or x not in SCALE_STEPS for x in scales):
            raise DermisError(f"{source}: 'scales' must be a list of output scales out of {list(SCALE_STEPS)}")
        return cls(actions, quit_after, base / report if report else None, source, tuple(float(x) for x in scales))

    @classmethod
    def from_file(cls, path) -> "Script":
        p = Path(path)
        if not p.is_file():
            raise DermisError(f"{p}: script file not found")
        try:
            data = json.loads(p.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise DermisError(f"{p}: not valid JSON ({exc})") from None
        return cls.from_dict(data, str(p), p.parent)

    def before(self, frame: int) -> list:
        return [{k: v for k, v in a.items() if k in BEFORE} for a in self.actions.get(frame, []) if set(a) & set(BEFORE)]

    def after(self, frame: int) -> list:
        return [{k: v for k, v in a.items() if k in AFTER} for a in self.actions.get(frame, []) if set(a) & set(AFTER)]

    def done(self, frames_drawn: int) -> bool:
        return self.quit_after is not None and frames_drawn >= self.quit_after
