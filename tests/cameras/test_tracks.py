"""Following a camera's detections from frame to frame: ids through crossings and missed
frames, ends, stillness and positions at any instant (for the trajectory matching)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from coffeebot.cameras.pipeline import Detection
from coffeebot.cameras.tracks import Tracker, TrackerSettings

SETTINGS = TrackerSettings()
PERIOD_S = 0.1


def seen(
    t_s: float, x_mm: float, y_mm: float, camera_id: str = "lab", cut: bool = False
) -> Detection:
    return Detection(
        t_s=t_s,
        x_mm=x_mm,
        y_mm=y_mm,
        length_mm=610.0,
        width_mm=510.0,
        axis_deg=0.0,
        area_mm2=311_100.0,
        camera_id=camera_id,
        cut=cut,
    )


def test_ids_name_the_camera_and_count_its_tracks() -> None:
    tracker = Tracker(SETTINGS)
    tracks = tracker.update([seen(0.0, 0.0, 0.0), seen(0.0, 2000.0, 0.0)], 0.0)
    tracks = tracker.update([seen(0.1, 0.0, 0.0), seen(0.1, 4000.0, 0.0, "hall")], 0.1)
    assert sorted(t.id for t in tracks) == ["hall-1", "lab-1", "lab-2"]


def test_two_objects_passing_800_mm_apart_keep_their_ids_through_missed_frames() -> None:
    """Paths crossing at right angles, one behind the other so that they pass 800 mm apart,
    with 10 mm of jitter and both unseen for three frames as they pass."""
    rng = np.random.default_rng(7)
    delay_s = 0.8 * math.sqrt(2)  # closest approach: 1 m/s each, 1000 mm x delay / sqrt(2)
    tracker = Tracker(SETTINGS)
    closest_mm = math.inf
    ids: dict[str, set[str]] = {"a": set(), "b": set()}
    for k in range(45):
        t_s = k * PERIOD_S
        where = {
            "a": np.array([1000.0 + 1000.0 * t_s, 1500.0]),
            "b": np.array([2000.0, 500.0 + 1000.0 * (t_s - delay_s)]),
        }
        closest_mm = min(closest_mm, float(np.linalg.norm(where["a"] - where["b"])))
        hidden = 15 <= k <= 17  # the closest approach is at 1.57 s
        detections = (
            [] if hidden else [seen(t_s, *p + rng.normal(0, 10, 2)) for p in where.values()]
        )
        rng.shuffle(detections)  # in no particular order, as contours come
        tracks = tracker.update(detections, t_s)
        assert len(tracks) == 2
        if not hidden:
            for name, p in where.items():
                nearest = min(tracks, key=lambda tr: math.dist((tr.latest.x_mm, tr.latest.y_mm), p))
                ids[name].add(nearest.id)
    assert closest_mm == pytest.approx(800.0, abs=15.0)
    assert [len(ids["a"]), len(ids["b"])] == [1, 1]
    assert ids["a"] != ids["b"]


def test_a_walker_unseen_for_half_a_second_keeps_its_id() -> None:
    """At 1.5 m/s it is 750 mm on, beyond the gate around where it was last seen but not
    around where it was heading."""
    tracker = Tracker(SETTINGS)
    for k in [*range(10), *range(15, 20)]:
        t_s = k * PERIOD_S
        tracks = tracker.update([seen(t_s, 1000.0 + 1500.0 * t_s, 1000.0)], t_s)
        assert [t.id for t in tracks] == ["lab-1"]


def test_a_detection_beyond_the_gate_starts_a_track_of_its_own() -> None:
    tracker = Tracker(SETTINGS)
    tracker.update([seen(0.0, 1000.0, 1000.0)], 0.0)
    tracks = tracker.update([seen(0.1, 1000.0 + SETTINGS.gate_mm + 50.0, 1000.0)], 0.1)
    assert [t.id for t in tracks] == ["lab-1", "lab-2"]
    assert tracks[0].latest.t_s == 0.0


def test_a_track_not_seen_ends_after_the_timeout_and_its_id_is_not_reused() -> None:
    tracker = Tracker(SETTINGS)
    for k in range(10):
        tracker.update([seen(k * PERIOD_S, 1000.0, 1000.0)], k * PERIOD_S)
    last_seen_s = 0.9
    just_in_time_s = last_seen_s + SETTINGS.end_after_s - PERIOD_S / 2
    assert [t.id for t in tracker.update([], just_in_time_s)] == ["lab-1"]
    too_late_s = last_seen_s + SETTINGS.end_after_s + PERIOD_S / 2
    assert tracker.update([], too_late_s) == []
    back_s = too_late_s + PERIOD_S
    assert [t.id for t in tracker.update([seen(back_s, 1000.0, 1000.0)], back_s)] == ["lab-2"]


def test_a_track_last_seen_leaving_the_view_ends_sooner_and_a_newcomer_gets_a_new_id() -> None:
    """A robot drives out through the image's border (its last blobs cut by it); 1.2 s later
    someone steps in there, 450 mm from where it was last seen: a new track, not the robot's.
    A track that vanished inside the view (occluded) still waits the full timeout."""
    tracker = Tracker(SETTINGS)
    for k in range(10):
        t_s = k * PERIOD_S
        tracker.update(
            [seen(t_s, 1000.0 + 200.0 * t_s, 0.0, cut=k >= 7), seen(t_s, 5000.0, 0.0)], t_s
        )
    gone_s = 0.9 + SETTINGS.left_view_after_s + PERIOD_S / 2
    assert [t.id for t in tracker.update([seen(gone_s, 5000.0, 0.0)], gone_s)] == ["lab-2"]
    newcomer_s = 2.1
    tracks = tracker.update([seen(newcomer_s, 1180.0, 440.0, cut=True)], newcomer_s)
    assert [t.id for t in tracks] == ["lab-2", "lab-3"]


def test_a_track_last_seen_leaving_the_view_keeps_its_id_through_a_few_missed_frames() -> None:
    tracker = Tracker(SETTINGS)
    for k in [*range(8), *range(11, 15)]:
        t_s = k * PERIOD_S
        tracks = tracker.update([seen(t_s, 1000.0 + 200.0 * t_s, 0.0, cut=k >= 5)], t_s)
        assert [t.id for t in tracks] == ["lab-1"]


def test_resample_interpolates_and_leaves_what_it_never_saw_unknown() -> None:
    tracker = Tracker(SETTINGS)
    for t_s, x, y in [(1.0, 0.0, 0.0), (1.1, 100.0, 50.0), (1.3, 100.0, 250.0)]:
        (track,) = tracker.update([seen(t_s, x, y)], t_s)
    positions = track.resample(np.array([1.0, 1.05, 1.2, 1.3, 0.9, 1.4]))
    np.testing.assert_allclose(
        positions[:4], [[0.0, 0.0], [50.0, 25.0], [100.0, 150.0], [100.0, 250.0]], atol=1e-9
    )
    assert np.isnan(positions[4:]).all()


def test_a_track_that_stops_is_still_once_it_has_stood_for_the_window() -> None:
    rng = np.random.default_rng(11)
    tracker = Tracker(SETTINGS)
    stopped_s, still_from_s = 2.0, math.inf
    for k in range(80):
        t_s = k * PERIOD_S
        x = 1000.0 + 500.0 * min(t_s, stopped_s)  # 0.5 m/s, then standing
        (track,) = tracker.update([seen(t_s, *np.array([x, 1000.0]) + rng.normal(0, 10, 2))], t_s)
        if track.still:
            still_from_s = min(still_from_s, t_s)
        else:
            assert still_from_s == math.inf  # once still, it stays still while it stands
    window_done_s = stopped_s + SETTINGS.still_window_s
    assert window_done_s - PERIOD_S <= still_from_s <= window_done_s + 3 * PERIOD_S


def test_a_track_creeping_slowly_is_not_still() -> None:
    tracker = Tracker(SETTINGS)
    creep_mm_s = 1.5 * SETTINGS.still_tolerance_mm / SETTINGS.still_window_s
    for k in range(80):
        t_s = k * PERIOD_S
        (track,) = tracker.update([seen(t_s, 1000.0 + creep_mm_s * t_s, 1000.0)], t_s)
        assert not track.still


def test_the_history_keeps_only_the_latest_positions() -> None:
    tracker = Tracker(SETTINGS.model_copy(update={"max_history": 20}))
    for k in range(50):
        (track,) = tracker.update([seen(k * PERIOD_S, 10.0 * k, 0.0)], k * PERIOD_S)
    history = track.history
    assert history.shape == (20, 3)
    np.testing.assert_allclose(history[[0, -1], 1], [300.0, 490.0])


def test_positions_next_to_a_blob_cut_by_the_border_are_not_given() -> None:
    """Driving in, the first three blobs were cut by the image's edge: the track is followed
    from its first sighting, but positions next to those are NaN, not a lagging centroid."""
    tracker = Tracker(SETTINGS)
    for k in range(10):
        (track,) = tracker.update([seen(k * PERIOD_S, 100.0 * k, 0.0, cut=k < 3)], k * PERIOD_S)
    path = track.resample(np.array([0.05, 0.25, 0.31, 0.35, 0.85]))
    assert np.isnan(path[:2]).all()
    np.testing.assert_allclose(path[2:], [[310.0, 0.0], [350.0, 0.0], [850.0, 0.0]])
    assert track.spans(0.0, 0.9) and not track.spans(-0.1, 0.9)
