"""The rig step: the rig check's summary before the first frame."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.containers import VerticalScroll
from textual.widgets import Footer, Static

from rigkit.capture.field import metres
from rigkit.reporting.scale import scale_source
from rigkit.rig.budget import budget_row
from rigkit.rig.check import check_rig
from rigkit.rig.optics import fov_deg
from rigkit.tui.header import FieldHeader
from rigkit.tui.screens.common import LaserLine, StepScreen, escape, session_of

PLANNED_RANGE_M = 300.0
"""Range the rig summary is given at when the profile names none (as `rigkit rig check`)."""

class RigScreen(StepScreen):
    """The rig check's summary: focal length, FOV, precision at the planned range."""

    step = "rig"

    def compose(self) -> ComposeResult:
        yield FieldHeader()
        with VerticalScroll():  # many warnings scroll (arrows, page keys) at 80x24
            yield Static(self._summary(), id="rig")
        yield LaserLine()
        yield Footer(compact=True)

    def on_mount(self) -> None:
        self.query_one(VerticalScroll).focus()

    def _summary(self) -> str:
        profile = session_of(self).rig()
        nominal = profile.nominal_range_m or PLANNED_RANGE_M
        check = check_rig(profile, [nominal])
        width, height = profile.image_size
        focal = profile.focal_px
        row = budget_row(check.model, nominal)
        lines = [
            f"[b]rig {profile.name}[/]  {width} x {height} px",
            f"focal length   {focal:,.0f} px ± {100 * profile.focal_tolerance:g} %",
            f"field of view  {fov_deg(focal, width):.2f} x {fov_deg(focal, height):.2f} deg",
            f"baselines      C_lr {metres(profile.baseline_lr.value_m)}, "
            f"C_lb {metres(profile.baseline_lb.value_m)}",
            f"scale          {escape(scale_source(profile))}",
            f"{f'at {nominal:g} m':<14} disparity {row.disparity_px:.1f} px, depth error "
            f"± {row.total_m:.1f} m ({100 * row.total_fraction:.1f} %)",
            "",
        ]
        if check.findings:
            lines.append(f"[b $warning]warnings ({len(check.findings)}):[/]")
            lines += [f"- {escape(f.message)}" for f in check.findings]
        else:
            lines.append("[b $success]no warnings[/]")
        lines += ["", "Press [b]n[/] to start with the left position."]
        return "\n".join(lines)
