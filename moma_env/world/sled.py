"""A sled towed by a ground robot through a rope on a pulley, in the pymunk space.

The sled is a dynamic box. Ground friction follows the robots' top-down
pattern (PivotJoints with zero bias to a body at rest, here the space's static
body) but acts at two contact points on the sled's x axis, ``+-friction_lever``
from its centre (:func:`friction_lever`), each capped at half the friction
force ``mass * friction_accel`` (N). Pure sliding meets the whole friction
force, pure spinning the friction torque of a uniformly loaded footprint, and
the two couple as on a real sled: a sideways pull at the front swings the sled
about its back until it trails the rope, like a trailer. A free sled slides to
a stop; a pull below the friction force does not move it.

The rope is a ``pymunk.SlideJoint`` from the robot's anchor to the sled's
anchor with ``min = 0``: slack below its ``max``, taut at it. The pulley acts
at every physics substep:

* sled **static** (kinematic, zero velocity: its pose stays bit-identical):
  the rope pays out freely as the robot drives away. The joint's ``max`` is
  ``max_rope`` (a leash the robot cannot pull past) and, after every substep,
  the rope length becomes ``min(max(length, anchor distance), max_rope)``;
  it never shortens by itself.
* sled **mobile** (dynamic): the reel rate ``r`` in [-1, 1] changes the length
  by ``-r * reel_speed * h`` per substep of ``h`` s, within
  ``[min_rope, max_rope]``; the joint's ``max`` is the length, so a taut rope
  drags the sled. ``r = 0`` holds the length.

The rope is stiff (:data:`ROPE_ERROR_BIAS`): a stretch is corrected within one
substep, so a reeled sled lags the rope's end by about one substep of reel.
Like a contact, a rope snapping taut may overshoot by up to one substep of the
anchors' relative travel before it pulls back. Its tension is capped at
``max_tension`` (N), so it never drags a sled through a wall or an obstacle
(contacts are stronger); and the winch stalls while the rope is stretched by
more than two substeps of reel (a stuck sled), so the length waits for the
sled instead of running away from it. A mobile robot reeling in a stuck sled
is winched towards it.
A joint between two non-dynamic bodies makes Chipmunk divide by zero (NaN
poses), so the rope leaves the space while the robot and the sled are both
static (:meth:`SledBody.sync_rope`). The rope also keeps the sled from
colliding with its own robot (``collide_bodies = False``); it collides with
walls, obstacles, other robots and other sleds.
"""

from __future__ import annotations

import math

import pymunk

from moma_env.world.config import SledConfig
from moma_env.world.ugv import UGVBody, set_body_locked

__all__ = ["SLED_FRICTION", "ROPE_ERROR_BIAS", "SledBody", "friction_lever"]

#: Coulomb friction coefficient between a sled and anything it touches.
SLED_FRICTION = 0.3
#: Fraction of a rope stretch left uncorrected after one second (pymunk's
#: ``Constraint.error_bias``): zero corrects a stretch within the next substep.
ROPE_ERROR_BIAS = 0.0


def friction_lever(length: float, width: float) -> float:
    """Mean distance (m) of the points of a ``length`` x ``width`` rectangle from its centre.

    Uniform ground pressure and Coulomb friction make the friction torque of a
    box spinning about its centre equal to the friction force times this lever
    (0.3826 times the side for a square).
    Closed form of the integral of ``sqrt(x^2 + y^2)`` over the rectangle.
    """
    a, b = 0.5 * length, 0.5 * width
    d = math.hypot(a, b)
    integral = (2.0 * a * b * d + a**3 * math.log((b + d) / a) + b**3 * math.log((a + d) / b)) / 6.0
    return integral / (a * b)


class SledBody:
    """pymunk body, shape, friction joints and rope of one sled, plus its pulley state.

    Attributes:
        config: the sled's configuration.
        robot: the robot that tows it.
        body, shape: the pymunk box (dynamic, or kinematic while static).
        rope: the SlideJoint from the robot's anchor to the sled's anchor.
        static: True while the sled is held still.
        rope_length: current rope length, anchor to anchor (m).
        reel_rate: last reel command in [-1, 1] (> 0 reels in); applied while mobile.
    """

    __slots__ = (
        "config",
        "robot",
        "body",
        "shape",
        "joints",
        "rope",
        "static",
        "rope_length",
        "reel_rate",
        "_rope_in_space",
    )

    def __init__(
        self,
        config: SledConfig,
        robot: UGVBody,
        space: pymunk.Space,
        shape_filter: pymunk.ShapeFilter,
    ):
        """Add the sled and its rope to ``space``; ``config.robot_anchor`` must be resolved.

        The rope starts at ``config.rope_length``, or taut at the anchors'
        distance if the sled starts farther away (never beyond ``max_rope``).
        """
        if config.robot_anchor is None:
            raise ValueError(f"sled {config.name!r} has no robot_anchor; build it through WorldConfig")
        self.config = config
        self.robot = robot
        x, y, yaw = config.initial_pose
        self.body = pymunk.Body()
        self.body.position = (x, y)
        self.body.angle = yaw
        self.shape = pymunk.Poly.create_box(self.body, config.size)
        # Mass on the shape: pymunk derives the box's moment from it, also when
        # the body turns dynamic again after a static phase.
        self.shape.mass = config.mass
        self.shape.friction = SLED_FRICTION
        self.shape.elasticity = 0.0
        self.shape.filter = shape_filter
        half_force = 0.5 * config.mass * config.friction_accel
        lever = friction_lever(*config.size)
        joints = []
        for offset in (lever, -lever):
            # The static body never moves, so with zero bias each joint only
            # brakes the velocity of its contact point (up to half_force); the
            # anchor on the static body does not matter.
            contact = pymunk.PivotJoint(space.static_body, self.body, (x, y), (offset, 0.0))
            contact.max_bias = 0.0
            contact.max_force = half_force
            joints.append(contact)
        self.joints = tuple(joints)
        space.add(self.body, self.shape, *self.joints)
        distance = self.anchor_distance()
        # Rounding of the anchors' distance does not count as a start beyond the rope.
        taut = distance > config.rope_length + 1e-9
        self.rope_length = min(distance, config.max_rope) if taut else config.rope_length
        # Built while the sled is dynamic: pymunk refuses a joint between two non-dynamic bodies.
        self.rope = pymunk.SlideJoint(
            robot.body, self.body, config.robot_anchor, config.sled_anchor, 0.0, self.rope_length
        )
        self.rope.error_bias = ROPE_ERROR_BIAS
        self.rope.max_force = config.max_tension
        # pymunk skips collisions between two bodies joined by a constraint with
        # collide_bodies False: the sled passes under its own robot, which would
        # otherwise fight the rope at short lengths.
        self.rope.collide_bodies = False
        self._rope_in_space = False
        self.reel_rate = 0.0
        self.static = False
        self.sync_rope()
        if config.static:
            self.set_static(True)

    def anchor_distance(self) -> float:
        """Current distance (m) between the rope's two anchors."""
        a = self.robot.body.local_to_world(self.config.robot_anchor)
        b = self.body.local_to_world(self.config.sled_anchor)
        return math.hypot(b.x - a.x, b.y - a.y)

    def reel(self, h: float) -> None:
        """Mobile sled, before a substep of ``h`` s: reel the rope in or out at the reel rate.

        Reeling in stalls while the rope is stretched by more than two substeps
        of reel (the sled is stuck): the length waits for the sled to follow.
        """
        cfg = self.config
        change = self.reel_rate * cfg.reel_speed * h  # > 0 shortens the rope
        if change > 0.0:
            if self.anchor_distance() - self.rope_length > 2.0 * cfg.reel_speed * h:
                return  # stalled
            self.rope_length = max(cfg.min_rope, self.rope_length - change)
        else:
            self.rope_length = min(cfg.max_rope, self.rope_length - change)
        self.rope.max = self.rope_length

    def pay_out(self) -> None:
        """Static sled, after a substep: the rope follows the robot out, up to ``max_rope``."""
        distance = self.anchor_distance()
        if distance > self.rope_length:
            self.rope_length = min(distance, self.config.max_rope)

    def sync_rope(self) -> None:
        """Keep the rope in the space exactly while the robot or the sled is dynamic."""
        wanted = not (self.static and self.robot.static)
        if wanted != self._rope_in_space:
            if wanted:
                self.body.space.add(self.rope)
            else:
                self.body.space.remove(self.rope)
            self._rope_in_space = wanted

    def set_static(self, static: bool) -> None:
        """Hold the sled still (kinematic, zero velocity) or release it (dynamic, from rest).

        Static: the rope becomes a leash of ``max_rope`` that pays out freely.
        Mobile: the rope holds its current length until reeled. The reel rate is kept.
        """
        if static == self.static:
            return
        set_body_locked(self.body, self.joints, static, self.config.mass, self.config.moment)
        self.rope.max = self.config.max_rope if static else self.rope_length
        self.static = static
        self.sync_rope()
