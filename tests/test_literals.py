"""Choice parameters are typed with ``Literal`` (issue 30), and each Literal names exactly the
choices the code accepts at run time (one list, checked here)."""

from __future__ import annotations

import inspect
from typing import get_args, get_type_hints

from so101sim.motion.tip import PATHS
from so101sim.recording.framing import NAMED_VIEWS, ViewName, view_direction, view_for_run
from so101sim.recording.settings import QUALITY_CHOICES, Quality, QualityChoice, VideoSettings
from so101sim.sim.moveplan import ShapeName, TipPath
from so101sim.sim.profiles import PROFILES
from so101sim.sim.results import SegmentKind, SegmentResult
from so101sim.sim.simulation import Simulation
from so101sim.viewer.passive import VIEWER_QUALITIES, ViewerQuality, open_viewer


def test_each_literal_is_the_list_the_code_checks():
    assert set(get_args(ShapeName)) == set(PROFILES)
    assert set(get_args(TipPath)) == set(PATHS)
    assert set(get_args(ViewName)) == set(NAMED_VIEWS)
    assert get_args(QualityChoice) == QUALITY_CHOICES == ("auto", *get_args(Quality))
    assert get_args(ViewerQuality) == VIEWER_QUALITIES
    assert set(get_args(SegmentKind)) == {"move", "hold", "step"}


def test_public_choice_parameters_carry_their_literal():
    move_to = inspect.signature(Simulation.move_to).parameters
    assert "TipPath" in str(move_to["path"].annotation)
    assert "Shape" in str(move_to["shape"].annotation)
    assert "ViewerQuality" in str(inspect.signature(open_viewer).parameters["quality"].annotation)
    assert "ViewName" in str(inspect.signature(view_for_run).parameters["view"].annotation)
    assert "ViewName" in str(inspect.signature(view_direction).parameters["name"].annotation)
    hints = get_type_hints(VideoSettings)
    assert hints["quality"] == QualityChoice and hints["view"] == ViewName
    assert get_type_hints(SegmentResult)["kind"] == SegmentKind
