"""Navigation: goals and their actionlib statuses, the global plan, the local controller.

The modules, one concern each:

- ``goals``: ``GoalBoard``, goals kept as an actionlib action server keeps them;
- ``commands``: a velocity command (``Command``), the stop, and a clamp to a limit;
- ``clearance``: what the laser sees, as clearance around the robot (``LocalObstacles``)
  and, for the controller, from what stands and what moves (``Clearance``);
- ``dynamic_window``: the dynamic window controller (``DynamicWindow``) and its
  ``Choice``;
- ``legs``: what drives one leg (``LegDriver``) and a tick's result (``Drive``);
- ``paths``: geometry along a planned path (projections, the point a distance along);
- ``driver``: ``Driver``, the agent's own driver to one target pose;
- ``navigator``: ``Navigator``, goals, the supervisor's legs and the driver together.

Frames: targets, paths and the pose estimate share the frame of the current sub-map
(the building's); obstacles and the controller's trajectories are in the robot's frame.

Settings: the body's limits and radius, the planner's margin and the controller's tuning
all come from the robot's ``RobotConfig`` (``cloudnav_core.params``).
"""
