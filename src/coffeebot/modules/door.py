"""Door module: doors passed on either side, named from the floor plan, and arrival."""

from __future__ import annotations

from coffeebot.config import RobotConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.messages import CURRENT_STATE, DOOR, MOVE_INSTRUCTION, ORDER_DISPATCH, RANGE_SCAN
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.perception.door import DoorDetector

RATE_SMOOTHING = 0.1
DEFAULT_SCAN_RATE_HZ = 10.0


class DoorModule(Module):
    """Wraps :class:`DoorDetector`; the scan rate is measured from the scans themselves."""

    name = "door"
    inputs = (RANGE_SCAN, CURRENT_STATE, ORDER_DISPATCH, MOVE_INSTRUCTION)
    outputs = (DOOR,)

    def __init__(self, config: RobotConfig, plan: FloorPlan) -> None:
        self.plan = plan
        self.detector = DoorDetector(config.tof.sensors, config.door, config.tof.cone_half_deg)
        self.scan_rate_hz = config.tof.scan_rate_hz or DEFAULT_SCAN_RATE_HZ

    def _target_door(self, ctx: ModuleContext) -> str | None:
        """Navigation's target if it names one, else the (first) door of the dispatched
        order's room."""
        instruction = ctx.board.latest(MOVE_INSTRUCTION)
        if instruction is not None and instruction.msg.target_door is not None:
            return instruction.msg.target_door
        dispatch = ctx.board.latest(ORDER_DISPATCH)
        if dispatch is None:
            return None
        try:
            return self.plan.find_room(dispatch.msg.room).door.id
        except KeyError:
            return None

    async def run(self, ctx: ModuleContext) -> None:
        self.detector.reset()
        previous_start: float | None = None
        with ctx.board.subscribe(RANGE_SCAN) as scans:
            async for envelope in scans:
                scan = envelope.msg
                if previous_start is not None and scan.cycle_start_s > previous_start:
                    rate = 1.0 / (scan.cycle_start_s - previous_start)
                    self.scan_rate_hz += RATE_SMOOTHING * (rate - self.scan_rate_hz)
                previous_start = scan.cycle_start_s
                state = ctx.board.latest(CURRENT_STATE)
                pose = state.msg.pose if state is not None and state.msg.pose.initialised else None
                self.detector.target_door = self._target_door(ctx)
                events = self.detector.update(
                    scan,
                    envelope.seq,
                    pose,
                    None
                    if pose is None
                    else self.plan.floor(pose.floor).view_near(pose.x_mm, pose.y_mm),
                    0.0 if pose is None else pose.speed_mm_s,
                    self.scan_rate_hz,
                )
                for event in events:
                    ctx.board.publish(DOOR, event)
