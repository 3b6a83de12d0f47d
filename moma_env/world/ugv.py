"""One omnidirectional ground robot in the pymunk space (top-down "tank" pattern).

The robot is a dynamic disk. Ground friction is modelled by a kinematic
*control body* whose velocity is the commanded world velocity, joined to the
robot by a PivotJoint (translation) and a GearJoint (rotation) whose bias is
zero and whose force/torque is capped at ``mass*max_accel`` and
``moment*max_yaw_accel``: the robot is pulled towards the commanded velocity
with limited traction and still collides with walls, obstacles and robots.

A *static* robot (a static marker) is switched to a kinematic body with zero
velocity and its joints are removed from the space: nothing moves it, its pose
stays bit-identical, and other robots bump into it as into a wall.
"""

from __future__ import annotations

import math

import pymunk

from moma_env.world.config import UGVConfig

__all__ = ["UGV_FRICTION", "UGVBody"]

#: Coulomb friction coefficient between a robot and anything it touches.
UGV_FRICTION = 0.3

# pymunk's public property setters, called directly on the per-substep path: an
# assignment ``body.velocity = v`` first passes through pymunk's pure-Python
# ``__setattr__`` (a typing helper that only forwards to ``object.__setattr__``).
_SET_VELOCITY = pymunk.Body.velocity.fset
_SET_ANGULAR_VELOCITY = pymunk.Body.angular_velocity.fset


def set_body_locked(body: pymunk.Body, joints: tuple, locked: bool, mass: float, moment: float) -> None:
    """Lock a body (kinematic, at rest, its friction joints out of the space) or release it
    (dynamic with ``mass`` and ``moment``, at rest, joints back in). The world's static lock."""
    space = body.space
    if locked:
        space.remove(*joints)
        body.body_type = pymunk.Body.KINEMATIC
    else:
        body.body_type = pymunk.Body.DYNAMIC
        if body.mass != mass:  # pymunk should have restored it from the shape
            body.mass = mass
            body.moment = moment
        space.add(*joints)
    body.velocity = (0.0, 0.0)
    body.angular_velocity = 0.0


class UGVBody:
    """pymunk body, shape and traction joints of one robot, plus its command.

    Attributes:
        config: the robot's configuration.
        body, shape: the pymunk disk (dynamic, or kinematic while static).
        static: True while the robot is locked in place.
        command: last clipped body-frame command (vx forward m/s, vy left m/s, omega rad/s).
    """

    __slots__ = ("config", "body", "shape", "control", "joints", "static", "command", "_substep", "_max_yaw_step")

    def __init__(self, config: UGVConfig, space: pymunk.Space, shape_filter: pymunk.ShapeFilter, substep: float):
        """Add the robot to ``space``; ``substep`` is the physics step (s) used by :meth:`drive`."""
        self.config = config
        self._substep = substep
        self._max_yaw_step = config.max_yaw_accel * substep
        x, y, yaw = config.initial_pose
        self.body = pymunk.Body()
        self.body.position = (x, y)
        self.body.angle = yaw
        self.shape = pymunk.Circle(self.body, config.radius)
        # Mass on the shape: pymunk recomputes mass and moment (uniform disk) from
        # it whenever the body becomes dynamic again after a static phase.
        self.shape.mass = config.mass
        self.shape.friction = UGV_FRICTION
        self.shape.elasticity = 0.0
        self.shape.filter = shape_filter
        self.control = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        self.control.position = (x, y)
        pivot = pymunk.PivotJoint(self.control, self.body, (0.0, 0.0), (0.0, 0.0))
        pivot.max_bias = 0.0
        pivot.max_force = config.mass * config.max_accel
        gear = pymunk.GearJoint(self.control, self.body, 0.0, 1.0)
        gear.max_bias = 0.0
        gear.max_force = config.moment * config.max_yaw_accel
        self.joints = (pivot, gear)
        self.command = (0.0, 0.0, 0.0)
        space.add(self.body, self.shape, self.control, *self.joints)
        self.static = False
        if config.static:
            self.set_static(True)

    def set_command(self, vx: float, vy: float, omega: float) -> None:
        """Store a finite body-frame command, clipped to the speed and yaw-rate limits."""
        cfg = self.config
        speed = math.hypot(vx, vy)
        if speed > cfg.max_speed:
            vx *= cfg.max_speed / speed
            vy *= cfg.max_speed / speed
        omega = min(max(omega, -cfg.max_yaw_rate), cfg.max_yaw_rate)
        self.command = (vx, vy, omega)

    def drive(self) -> None:
        """Aim the control body along the command, rotated into the world frame.

        Called before every physics substep. pymunk (Chipmunk) integrates the
        positions at the start of a step with the velocities solved in the step
        before, so the velocity solved now moves the body during the *next*
        substep, in a straight line. Aiming it along the heading in the middle of
        that substep, with the chord's length, makes the line a chord of the
        commanded arc: a constant command drives an exact circle at the
        commanded speed, with no sideways drift. The yaw rate expected in the
        coming substep is the commanded one, limited by the yaw acceleration.
        """
        vx, vy, omega = self.command
        body = self.body
        rate = body.angular_velocity
        step = self._max_yaw_step
        h = self._substep
        # min(max(omega, rate - step), rate + step), without the builtins' calls.
        low, high = rate - step, rate + step
        next_rate = low if low > omega else omega
        if high < next_rate:
            next_rate = high
        half_turn = 0.5 * next_rate * h
        angle = body.angle + rate * h + half_turn
        # Chord of an arc = arc length * sin(half_turn) / half_turn.
        chord = math.sin(half_turn) / half_turn if half_turn != 0.0 else 1.0
        c, s = chord * math.cos(angle), chord * math.sin(angle)
        control = self.control
        _SET_VELOCITY(control, (c * vx - s * vy, s * vx + c * vy))
        _SET_ANGULAR_VELOCITY(control, omega)

    def set_static(self, static: bool) -> None:
        """Lock the robot in place (kinematic, zero velocity) or release it (dynamic)."""
        if static == self.static:
            return
        set_body_locked(self.body, self.joints, static, self.config.mass, self.config.moment)
        self.control.velocity = (0.0, 0.0)
        self.control.angular_velocity = 0.0
        self.command = (0.0, 0.0, 0.0)
        self.static = static
