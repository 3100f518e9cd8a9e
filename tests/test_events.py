"""Events derived in memory from what robots publish and what the server does."""

from __future__ import annotations

from cloudnav_core.times import RobotClocks
from telemetry.domain.events import (
    BATTERY_LOW,
    SILENT_AFTER_S,
    STARTING_GRACE_S,
    STUCK_AFTER_S,
    EventDeriver,
    Kind,
    Severity,
)


def status(code: int, goal: str = "g1", text: str = "") -> dict:
    return {"status_list": [{"goal_id": {"id": goal}, "status": code, "text": text}]}


def localisation(state: str) -> dict:
    return {"message": f"{state} now", "values": [{"key": "state", "value": state}]}


def kinds(drafts: list) -> list[str]:
    """The kinds of ``drafts`` other than clearings (see the clearing tests below)."""
    return [d.kind for d in drafts if d.kind is not Kind.ALERT_CLEARED]


def cleared(drafts: list) -> set[Kind]:
    return {kind for d in drafts for kind in d.clears}


def test_a_robot_connecting_is_news_and_leaving_is_an_alert() -> None:
    deriver = EventDeriver()
    [came] = deriver.connected("r1", 10.0)
    [left] = deriver.disconnected("r1", 20.0)
    assert (came.kind, came.alert, came.actor) == (Kind.CONNECTED, False, "robot:r1")
    assert (left.kind, left.alert, left.time) == (Kind.DISCONNECTED, True, 20.0)


def test_an_aborted_goal_is_an_alert_once_with_its_reason() -> None:
    deriver = EventDeriver()
    deriver.connected("r1", 0.0)
    assert kinds(deriver.nav_status("r1", status(1), 1.0)) == []
    [aborted] = deriver.nav_status("r1", status(4, text="no path to the goal"), 2.0)
    assert aborted.kind == Kind.GOAL_ABORTED
    assert aborted.severity == Severity.ERROR
    assert aborted.data["reason"] == "no path to the goal"
    assert "no path to the goal" in aborted.message
    assert deriver.nav_status("r1", status(4, text="no path to the goal"), 3.0) == []
    assert kinds(deriver.nav_status("r1", status(5, goal="g2"), 4.0)) == [Kind.GOAL_ABORTED]


def test_a_robot_getting_lost_is_an_alert_on_the_change_only() -> None:
    deriver = EventDeriver()
    deriver.localisation("r1", localisation("localised"), 0.5)
    assert kinds(deriver.localisation("r1", localisation("lost"), 1.0)) == [Kind.LOST]
    assert deriver.localisation("r1", localisation("lost"), 2.0) == []
    # found again: news, not an alert (see the relocalisation tests below)
    assert kinds(deriver.localisation("r1", localisation("localised"), 3.0)) == [Kind.RELOCALISED]
    assert kinds(deriver.localisation("r1", localisation("lost"), 4.0)) == [Kind.LOST]


def test_a_low_battery_is_told_once_until_it_recovers() -> None:
    deriver = EventDeriver()
    assert deriver.battery("r1", {"percentage": 0.5}, 1.0) == []
    [low] = deriver.battery("r1", {"percentage": BATTERY_LOW - 0.01}, 2.0)
    assert low.kind == Kind.BATTERY_LOW
    assert low.alert
    assert deriver.battery("r1", {"percentage": 0.1}, 3.0) == []
    assert kinds(deriver.battery("r1", {"percentage": 0.9}, 4.0)) == []
    assert kinds(deriver.battery("r1", {"percentage": 0.1}, 5.0)) == [Kind.BATTERY_LOW]
    assert deriver.battery("r1", {"percentage": None}, 6.0) == []


def test_a_connected_robot_that_says_nothing_goes_silent_once() -> None:
    deriver = EventDeriver()
    deriver.connected("r1", 0.0)
    assert deriver.tick(SILENT_AFTER_S - 1) == []
    assert kinds(deriver.tick(SILENT_AFTER_S + 1)) == [Kind.SILENT]
    assert deriver.tick(SILENT_AFTER_S + 2) == []
    deriver.heard("r1", SILENT_AFTER_S + 3)
    assert kinds(deriver.tick(SILENT_AFTER_S + 4)) == []


def test_a_robot_with_a_goal_that_does_not_move_is_stuck() -> None:
    deriver = EventDeriver()
    deriver.connected("r1", 0.0)
    deriver.pose("r1", "b/A", 1.0, 1.0, 0.0)
    deriver.nav_status("r1", status(1), 0.0)
    for t in range(1, int(STUCK_AFTER_S) + 5):
        deriver.pose("r1", "b/A", 1.0 + 0.001 * t, 1.0, float(t))
        drafts = deriver.tick(float(t))
        if drafts:
            break
    assert kinds(drafts) == [Kind.STUCK]
    assert drafts[0].building == "b"
    assert deriver.tick(float(t) + 1) == []


def test_a_moving_robot_or_one_without_a_goal_is_not_stuck() -> None:
    deriver = EventDeriver()
    deriver.connected("r1", 0.0)
    deriver.nav_status("r1", status(1), 0.0)
    for t in range(1, int(STUCK_AFTER_S) * 2):
        deriver.pose("r1", "b/A", 0.1 * t, 0.0, float(t))
        assert kinds(deriver.tick(float(t))) == []
    deriver.nav_status("r1", status(3), 100.0)
    for t in range(100, 100 + int(STUCK_AFTER_S) * 2):
        deriver.pose("r1", "b/A", 0.0, 0.0, float(t))
        assert kinds(deriver.tick(float(t))) == []


class RobotOnItsClock:
    """A robot whose clock runs at ``pace`` of the server's, saying its goal is active (a
    stamped status) once a server second, and standing still at (1, 1)."""

    def __init__(self, pace: float, start: float = 1000.0) -> None:
        self.server = 0.0
        self.robot = start
        self.pace = pace
        self.clocks = RobotClocks(lambda: self.server)
        self.deriver = EventDeriver(clocks=self.clocks)
        self.deriver.connected("r1", 0.0)
        self.second()

    def second(self) -> list:
        """One server second on: the robot's status and pose, then the deriver's tick."""
        self.server += 1.0
        self.robot += self.pace
        msg = status(1) | {"header": {"stamp": {"sec": int(self.robot), "nanosec": 0}}}
        self.clocks.heard("r1", msg)
        self.deriver.nav_status("r1", msg, self.server)
        self.deriver.pose("r1", "b/A", 1.0, 1.0, self.server)
        return self.deriver.tick(self.server)


def test_a_robot_is_stuck_after_its_own_clock_s_seconds_not_the_server_s() -> None:
    slow = RobotOnItsClock(pace=0.25)  # a simulation at a quarter of real time
    for _ in range(int(STUCK_AFTER_S) * 3):  # 90 server seconds: 22.5 of its own
        assert kinds(slow.second()) == []
    while not (drafts := slow.second()):
        assert slow.server < STUCK_AFTER_S * 5, "never stuck"
    assert kinds(drafts) == [Kind.STUCK]
    assert f"in {int(STUCK_AFTER_S) + 1} s" in drafts[0].message
    assert slow.server > STUCK_AFTER_S * 4  # 30 of its seconds took 120 of the server's
    held = slow.deriver.stuck_for("r1", slow.server)  # since its last move
    assert held == STUCK_AFTER_S + 1
    for _ in range(8):
        slow.second()
    assert slow.deriver.stuck_for("r1", slow.server) == held + 2.0  # 8 server s, 2 of its own


def test_a_robot_faster_than_real_time_is_stuck_after_the_server_s_seconds_too() -> None:
    fast = RobotOnItsClock(pace=8.0)  # a test simulation at eight times real time
    for _ in range(int(STUCK_AFTER_S)):  # 240 of its seconds: waits on the server count once
        assert kinds(fast.second()) == []
    assert kinds(fast.second()) == [Kind.STUCK]


def test_a_robot_whose_clock_is_set_back_counts_its_progress_afresh() -> None:
    robot = RobotOnItsClock(pace=1.0)
    for _ in range(int(STUCK_AFTER_S) - 5):
        assert kinds(robot.second()) == []
    robot.robot = 0.0  # its simulation restarted: its clock begins again
    for _ in range(int(STUCK_AFTER_S) - 5):
        assert kinds(robot.second()) == []
    while not (drafts := robot.second()):
        assert robot.server < STUCK_AFTER_S * 3, "never stuck"
    assert kinds(drafts) == [Kind.STUCK]


def test_a_robot_with_no_stamps_is_timed_on_the_server_s_clock() -> None:
    deriver = EventDeriver(clocks=RobotClocks(lambda: 0.0))
    deriver.connected("r1", 0.0)
    deriver.nav_status("r1", status(1), 0.0)
    deriver.pose("r1", "b/A", 1.0, 1.0, 0.0)
    deriver.heard("r1", STUCK_AFTER_S)
    assert kinds(deriver.tick(STUCK_AFTER_S)) == []
    deriver.heard("r1", STUCK_AFTER_S + 1)
    assert kinds(deriver.tick(STUCK_AFTER_S + 1)) == [Kind.STUCK]


def test_a_dead_man_stop_names_whoever_was_driving() -> None:
    [stop] = EventDeriver().teleop("r1", Kind.DEADMAN_STOP, "user:operator", 1.0)
    assert (stop.actor, stop.severity, stop.alert) == ("user:operator", Severity.WARNING, False)
    assert "user:operator" in stop.message


def test_a_robot_that_left_is_forgotten() -> None:
    deriver = EventDeriver()
    deriver.connected("r1", 0.0)
    deriver.disconnected("r1", 1.0)
    assert deriver.tick(100.0) == []
    assert not deriver.watching()


def placed(state: str, map_id: str = "", source: str = "") -> dict:
    values = [{"key": "state", "value": state}, {"key": "map_id", "value": map_id}]
    return {"message": state, "values": [*values, {"key": "source", "value": source}]}


def test_a_goal_reached_or_cancelled_is_news_once() -> None:
    deriver = EventDeriver()
    deriver.nav_status("r1", status(1), 1.0)
    [reached] = deriver.nav_status("r1", status(3), 2.0)
    assert (reached.kind, reached.severity, reached.alert) == (
        Kind.GOAL_REACHED,
        Severity.INFO,
        False,
    )
    assert reached.data["goal"] == "g1"
    assert deriver.nav_status("r1", status(3), 3.0) == []
    assert kinds(deriver.nav_status("r1", status(2, goal="g2"), 4.0)) == [Kind.GOAL_CANCELLED]
    assert kinds(deriver.nav_status("r1", status(8, goal="g3"), 5.0)) == [Kind.GOAL_CANCELLED]


def test_a_goal_sent_names_who_sent_it_and_where() -> None:
    deriver = EventDeriver()
    deriver.pose("r1", "b/Hall", 0.0, 0.0, 1.0)
    goal = {"header": {"frame_id": "b/Lab"}, "pose": {"position": {"x": 2.5, "y": -1.0}}}
    [sent] = deriver.goal_sent("r1", "user:ann", goal, 2.0)
    assert (sent.kind, sent.actor, sent.building) == (Kind.GOAL_SENT, "user:ann", "b")
    assert dict(sent.data) == {"map_id": "b/Lab", "x": 2.5, "y": -1.0}


def test_a_tag_read_then_the_map_it_names_is_one_tag_event_and_no_relocalisation() -> None:
    deriver = EventDeriver()
    assert deriver.localisation("r1", placed("localised", "b/Hall", "initial pose"), 1.0) == []
    [read] = deriver.localisation("r1", placed("entering", "b/Lab", "tag 7"), 2.0)
    assert (read.kind, read.data["source"], read.data["map_id"]) == (
        Kind.TAG_READ,
        "tag 7",
        "b/Lab",
    )
    assert deriver.localisation("r1", placed("entering", "b/Lab", "tag 7"), 2.1) == []
    assert deriver.localisation("r1", placed("localised", "b/Lab", "tag 7"), 3.0) == []


def test_a_lost_robot_found_again_or_placed_by_hand_is_relocalised() -> None:
    deriver = EventDeriver()
    deriver.localisation("r1", placed("localised", "b/Hall", "tag 1"), 1.0)
    assert kinds(deriver.localisation("r1", placed("lost"), 2.0)) == [Kind.LOST]
    [found, _cleared] = deriver.localisation("r1", placed("localised", "b/Hall", "tag 1"), 3.0)
    assert (found.kind, found.data["source"]) == (Kind.RELOCALISED, "tag 1")
    [by_hand] = deriver.localisation("r1", placed("localised", "b/Lab", "initial pose"), 4.0)
    assert by_hand.kind == Kind.RELOCALISED
    assert deriver.localisation("r1", placed("localised", "b/Lab", "initial pose"), 5.0) == []


def test_taking_and_releasing_the_teleop_lock_name_the_holder() -> None:
    deriver = EventDeriver()
    [taken] = deriver.teleop("r1", Kind.TELEOP_TAKEN, "user:op", 1.0)
    [released] = deriver.teleop("r1", Kind.TELEOP_RELEASED, "user:op", 2.0)
    assert (taken.actor, taken.message) == ("user:op", "user:op took the teleop lock of r1")
    assert (released.kind, released.actor) == (Kind.TELEOP_RELEASED, "user:op")


def test_alerts_clear_themselves_when_their_condition_ends() -> None:
    deriver = EventDeriver()
    deriver.connected("r1", 0.0)
    deriver.localisation("r1", placed("localised", "b/Hall", "tag 1"), 1.0)
    deriver.localisation("r1", placed("lost"), 2.0)
    assert cleared(deriver.localisation("r1", placed("localised", "b/Hall", "tag 1"), 3.0)) == {
        Kind.LOST
    }
    deriver.battery("r1", {"percentage": 0.1}, 4.0)
    [charged] = deriver.battery("r1", {"percentage": 0.5}, 5.0)
    assert (charged.kind, charged.clears, charged.alert) == (
        Kind.ALERT_CLEARED,
        {Kind.BATTERY_LOW},
        False,
    )
    assert deriver.battery("r1", {"percentage": 0.6}, 6.0) == []
    assert cleared(deriver.connected("r1", 7.0)) == {Kind.DISCONNECTED, Kind.SILENT}


def test_a_silent_robot_heard_again_and_a_stuck_one_moving_again_are_cleared() -> None:
    deriver = EventDeriver()
    deriver.connected("r1", 0.0)
    assert kinds(deriver.tick(SILENT_AFTER_S + 1)) == [Kind.SILENT]
    deriver.pose("r1", "b/A", 0.0, 0.0, SILENT_AFTER_S + 2)
    assert cleared(deriver.tick(SILENT_AFTER_S + 3)) == {Kind.SILENT}
    deriver.nav_status("r1", status(1), 10.0)
    assert kinds(deriver.tick(10.0 + STUCK_AFTER_S + 1)) == [Kind.SILENT, Kind.STUCK]
    deriver.pose("r1", "b/A", 1.0, 0.0, 50.0)
    assert cleared(deriver.tick(50.5)) == {Kind.SILENT, Kind.STUCK}


def test_a_new_goal_clears_an_aborted_one() -> None:
    deriver = EventDeriver()
    deriver.connected("r1", 0.0)
    deriver.nav_status("r1", status(1, goal="g1"), 1.0)
    deriver.nav_status("r1", status(4, goal="g1"), 2.0)
    assert cleared(deriver.nav_status("r1", status(4, goal="g1"), 2.5)) == set()
    assert cleared(deriver.nav_status("r1", status(1, goal="g2"), 3.0)) == {Kind.GOAL_ABORTED}
    # another goal failing replaces the last failure: one open alert, the newest
    [failed] = deriver.nav_status("r1", status(5, goal="g3"), 4.0)
    assert (failed.kind, failed.clears) == (Kind.GOAL_ABORTED, {Kind.GOAL_ABORTED})


def test_a_robot_lost_before_its_first_localisation_is_starting_not_lost() -> None:
    deriver = EventDeriver()
    deriver.connected("r1", 0.0)
    assert kinds(deriver.localisation("r1", placed("lost"), 0.1)) == []
    deriver.heard("r1", STARTING_GRACE_S - 1)
    assert kinds(deriver.tick(STARTING_GRACE_S - 1)) == []
    deriver.localisation("r1", placed("localised", "b/Hall", "tag 0"), STARTING_GRACE_S - 0.5)
    assert kinds(deriver.tick(STARTING_GRACE_S + 1)) == []


def test_a_robot_that_never_localises_after_connecting_is_lost_once() -> None:
    deriver = EventDeriver()
    deriver.connected("r1", 0.0)
    deriver.localisation("r1", placed("lost"), 0.1)
    for t in range(1, int(STARTING_GRACE_S) + 5):
        deriver.heard("r1", float(t))
        drafts = deriver.tick(float(t))
        if drafts:
            break
    assert kinds(drafts) == [Kind.LOST]
    assert t > STARTING_GRACE_S
    assert kinds(deriver.tick(float(t) + 1)) == []
    found = deriver.localisation("r1", placed("localised", "b/Hall", "tag 0"), t + 2.0)
    assert cleared(found) == {Kind.LOST}
