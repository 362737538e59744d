"""The mock arm's world (pure, no rclpy): the controller's law, the arm it moves and the faults
a real lab has, each a named setting drawn from a seed.

The press (``robot.press``) never sees this module: it acts on what the robot reports (pose,
wrench). The mock arm node runs ``ArmModel`` in place of the robot; the unit tests close the
loop ``PressController`` -> ``ArmModel`` -> ``PressController``.

What the world adds to the perfect spring-damper arm (``Faults``; docs/simulated_world.md has
the range a lab meets and the source of each):

- *read only* (the estimate is wrong, the arm is not pushed): ``wrench_offset`` [N] (3-vector:
  model and sensor bias), ``offset_gradient`` [N/m] (the bias changes with the configuration:
  ``offset_gradient`` times a fixed random unit matrix times the displacement from the start),
  ``wrench_drift`` [N/s] (3-vector, linear in time), ``wrench_noise`` [N] (std per axis and
  sample);
- *real forces* (the arm is pushed and the estimate reads them): ``static_force`` [N]
  (3-vector: payload error, cable pull; + z is upward, as a contact pushes);
- *dynamics only* (joint friction is not in the link-side torque estimate):
  ``coulomb_friction`` [N] (stick-slip per axis), ``viscous_friction`` [N s/m];
- *the scene is wrong*: ``surface_offset`` [m] (true surface z minus the scene's),
  ``platform_stiffness`` [N/m], ``platform_damping`` [N s/m].

The controller's own behaviour is in ``ControlLaw``: target filter, state and output filters,
stiffness clamp, error clip, torque rate limit and the activation transient.
"""

from __future__ import annotations

from dataclasses import dataclass, replace as _replace
from collections.abc import Sequence

import numpy as np

from .press import Platform, PressController, PressOutcome, Workspace

Vec3 = tuple[float, float, float]
ZERO3: Vec3 = (0.0, 0.0, 0.0)


def platform_under(platforms: Sequence[Platform], position: np.ndarray
                   ) -> tuple[int | None, float]:
    """Index of the first of ``platforms`` whose disc (``radius`` around its centre, in x-y)
    holds the sensor at ``position`` (x, y, z) [m], and the sensor's depth below that
    platform's surface [m] (0 when above it); (None, 0.0) when no platform is under it. The
    mock arm (contact force) and the mock camera (which fabric to show) both ask this."""
    pos = np.asarray(position, dtype=float)
    for i, p in enumerate(platforms):
        c = np.asarray(p.position, dtype=float)
        if np.linalg.norm(pos[:2] - c[:2]) <= p.radius:
            return i, max(0.0, float(c[2] - pos[2]))
    return None, 0.0


@dataclass
class PressCounter:
    """The mock camera's count of presses (``presses``: the current press's number, from 1).

    A press begins when the sensor touches a platform (``contact``: a force over ``force_n``
    [N] with the sensor at or below the platform's surface) and ends only once the sensor is
    ``clear_m`` [m] above every surface or off every platform: a force that dips for a sample
    during one press (a late wrench on a loaded machine) never starts another press, so each
    press draws its faults once."""

    force_n: float = 0.05
    clear_m: float = 0.001
    presses: int = 0
    in_contact: bool = False

    def update(self, platforms: Sequence[Platform], position: np.ndarray | None,
               force: float) -> tuple[int | None, bool, bool]:
        """(platform index under the sensor or None, in contact now, a new press began now)."""
        idx, depth = (None, 0.0) if position is None else platform_under(platforms, position)
        contact = idx is not None and force > self.force_n and depth > 0
        began = contact and not self.in_contact
        if began:
            self.presses += 1
            self.in_contact = True
        elif not contact and (idx is None or float(platforms[idx].position[2])
                              - float(np.asarray(position, dtype=float)[2]) < -self.clear_m):
            self.in_contact = False
        return idx, contact, began


def shift_surfaces(scene: Workspace, dz: float) -> Workspace:
    """The scene with every platform's surface ``dz`` [m] higher (lower if < 0)."""
    if not dz:
        return scene
    return _replace(scene, platforms=tuple(
        p.replace(position=(p.position[0], p.position[1], p.position[2] + dz))
        for p in scene.platforms))


@dataclass(frozen=True)
class ControlLaw:
    """The translational law of the Cartesian impedance controller a robot profile names, as the
    mock arm runs it: one control cycle every ``1 / rate_hz`` s, the force held in between.

    Per cycle, per axis (x_t the commanded target, x_f the filtered target, x, v the arm):

    1. target filter: ``x_f <- (1 - target_filter) x_t + target_filter x_f`` (an exponential
       moving average; 0 = none; CRISP ``filter.target_pose``);
    2. state filter: the controller's x, v are the measured ones through the same kind of
       moving average with weight ``state_filter`` (CRISP 2.3 ``filter.q`` / ``filter.dq``);
    3. error: ``e = clip(x_f - x, -clip, clip)`` with ``clip`` = (``lateral_error_clip``,
       ``lateral_error_clip``, ``error_clip``) (CRISP ``task.error_clip.x/y/z`` with
       ``limit_error``; inf = none; ``lateral_error_clip`` 0 = ``error_clip``);
    4. force: ``F = K e - D v`` with ``K = min(stiffness, max_stiffness)`` (CRISP 2.3 clamps
       the translational stiffness at ``variable_max_stiffness.translational``) and
       ``D = damping`` if > 0, else ``2 sqrt(stiffness)`` (from the *requested* stiffness:
       CRISP ``task.d_pos_*``, franka_ros2's and multipanda_ros2's examples);
    5. output filter: ``F <- (1 - output_filter) F + output_filter F_prev`` (CRISP 2.3
       ``filter.output_torque``, seen at the end effector);
    6. rate limit: ``F <- F_prev + clip(F - F_prev, -max_force_step, max_force_step)`` (CRISP's
       ``max_delta_tau`` per joint and cycle, seen at the end effector; inf = none).

    After each activation the filtered target is off by ``activation_jump`` [m] for
    ``activation_jump_s`` [s] (CRISP v1.0.0's target filter starts from a pose that is not the
    measured one; the error clip bounds what it pushes with).

    Units: N/m, N s/m, Hz, m, N, s.
    """

    stiffness: float
    damping: float = 0.0
    rate_hz: float = 1000.0
    target_filter: float = 0.0
    error_clip: float = float("inf")
    lateral_error_clip: float = 0.0
    max_force_step: float = float("inf")
    max_stiffness: float = float("inf")
    state_filter: float = 0.0
    output_filter: float = 0.0
    activation_jump: Vec3 = ZERO3
    activation_jump_s: float = 0.0

    def __post_init__(self) -> None:
        if not self.stiffness > 0 or not self.rate_hz > 0 or not self.max_stiffness > 0:
            raise ValueError(f"stiffness ({self.stiffness}), max_stiffness "
                             f"({self.max_stiffness}) and rate_hz ({self.rate_hz}) must be "
                             "positive")
        for name in ("target_filter", "state_filter", "output_filter"):
            if not 0.0 <= getattr(self, name) < 1.0:
                raise ValueError(f"{name} must be in [0, 1), got {getattr(self, name)}")
        if not self.error_clip > 0 or not self.max_force_step > 0:
            raise ValueError("error_clip and max_force_step must be positive (inf = none)")
        if not self.lateral_error_clip >= 0:
            raise ValueError("lateral_error_clip must be >= 0 (0 = error_clip)")
        if self.activation_jump_s < 0:
            raise ValueError("activation_jump_s must be >= 0")

    @property
    def k(self) -> float:
        """The stiffness the controller applies [N/m] (clamped at ``max_stiffness``)."""
        return min(self.stiffness, self.max_stiffness)

    @property
    def d(self) -> float:
        """The damping the controller computes [N s/m]."""
        return self.damping if self.damping > 0 else 2.0 * float(np.sqrt(self.stiffness))

    @property
    def clip(self) -> np.ndarray:
        """The pose error clip per axis x, y, z [m] (inf: none)."""
        xy = self.lateral_error_clip or self.error_clip
        return np.array([xy, xy, self.error_clip])

    @property
    def max_static_force(self) -> float:
        """Largest force the law pushes with at rest [N] (``K * error_clip``; inf if unclipped)."""
        return self.k * self.error_clip

    def replace(self, **kw) -> ControlLaw:
        return _replace(self, **kw)


# CRISP 2.3.x defaults over v1.0.0's law (the press's 1000 N/m is clamped at 900; the filters
# on q, dq and the output torque default to 0.5): see docs/simulated_world.md.
CRISP_23 = {"max_stiffness": 900.0, "state_filter": 0.5, "output_filter": 0.5}


@dataclass(frozen=True)
class Faults:
    """The faults of one simulated world (module docstring): units N, N/m, N/s, N s/m, m.
    ``seed`` draws the noise and the direction of the configuration-dependent offset."""

    wrench_offset: Vec3 = ZERO3
    offset_gradient: float = 0.0
    wrench_drift: Vec3 = ZERO3
    wrench_noise: float = 0.0
    static_force: Vec3 = ZERO3
    coulomb_friction: float = 0.0
    viscous_friction: float = 0.0
    surface_offset: float = 0.0
    platform_stiffness: float = 2e4
    platform_damping: float = 50.0
    seed: int = 0

    def __post_init__(self) -> None:
        if not self.platform_stiffness > 0:
            raise ValueError(f"platform_stiffness must be positive, got "
                             f"{self.platform_stiffness}")
        for name in ("offset_gradient", "wrench_noise", "coulomb_friction",
                     "viscous_friction", "platform_damping"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")

    def replace(self, **kw) -> Faults:
        return _replace(self, **kw)

    @staticmethod
    def draw(rng: np.random.Generator) -> Faults:
        """A world from the ranges a lab meets (docs/simulated_world.md): offset up to 5 N in
        any direction drifting up to 0.02 N/s, a configuration-dependent offset up to 10 N/m,
        noise 0.05-0.3 N, a static force up to 4 N up or down and 3 N sideways, Coulomb friction
        up to 2 N, viscous up to 5 N s/m, the surface +-5 mm off, platforms 5e2-5e4 N/m."""
        def ball(r: float) -> Vec3:
            v = rng.standard_normal(3)
            return tuple(float(x) for x in v / np.linalg.norm(v) * r * rng.uniform() ** (1 / 3))
        side = rng.standard_normal(2)
        side = side / np.linalg.norm(side) * rng.uniform(0.0, 3.0)
        return Faults(
            wrench_offset=ball(5.0), offset_gradient=float(rng.uniform(0.0, 10.0)),
            wrench_drift=ball(0.02), wrench_noise=float(rng.uniform(0.05, 0.3)),
            static_force=(float(side[0]), float(side[1]), float(rng.uniform(-4.0, 4.0))),
            coulomb_friction=float(rng.uniform(0.0, 2.0)),
            viscous_friction=float(rng.uniform(0.0, 5.0)),
            surface_offset=float(rng.uniform(-0.005, 0.005)),
            platform_stiffness=float(np.exp(rng.uniform(np.log(5e2), np.log(5e4)))),
            platform_damping=float(rng.uniform(0.0, 100.0)),
            seed=int(rng.integers(2 ** 31)))


def _stack(faults: Sequence[Faults], name: str) -> np.ndarray:
    return np.array([getattr(f, name) for f in faults], dtype=float)


class Worlds:
    """``n`` mock arms under one Cartesian impedance ``law``, each in its own world
    (``faults[i]``, ``mass[i]``), simulated together (arrays of shape (n, 3)): a point mass
    [kg], gravity compensated, pushed by the controller's force (``ControlLaw``), the world's
    static force and friction, computed once per control cycle and held over it. Platforms
    push back with a spring ``platform_stiffness`` [N/m] (gel, fabric and platform in series)
    and a damper ``platform_damping`` [N s/m] when the sensor is below their *true* surface
    (the scene's + ``surface_offset``) within their radius. ``wrench()`` is what the robot
    reports. Every control cycle is one sample. Positions in m, time in s, forces in N.
    """

    _STICK = 1e-4      # [m/s] below this speed an axis sticks if friction can hold it

    def __init__(self, scene: Workspace, start: np.ndarray, law: ControlLaw,
                 faults: Sequence[Faults], mass: Sequence[float] | float = 3.0) -> None:
        n = len(faults)
        self.n, self.scene, self.law = n, scene, law
        self.m = np.broadcast_to(np.asarray(mass, dtype=float), (n,)).copy()
        if not np.all(self.m > 0):
            raise ValueError(f"mass must be positive, got {mass}")
        self.k, self.d, self.h = law.k, law.d, 1.0 / law.rate_hz
        self.centres = np.array([p.position for p in scene.platforms], dtype=float)  # (P, 3)
        self.radii = np.array([p.radius for p in scene.platforms], dtype=float)      # (P,)
        self._centres_xy, self._radii2 = self.centres[None, :, :2], self.radii[None, :] ** 2
        self.dz = _stack(faults, "surface_offset")
        self.kp, self.dp = _stack(faults, "platform_stiffness"), _stack(faults,
                                                                         "platform_damping")
        self.static = _stack(faults, "static_force")
        self.offset, self.drift = _stack(faults, "wrench_offset"), _stack(faults, "wrench_drift")
        self.noise = _stack(faults, "wrench_noise")
        self.fc, self.fv = _stack(faults, "coulomb_friction"), _stack(faults, "viscous_friction")
        self._frictionless = not (np.any(self.fc) or np.any(self.fv))
        self._rngs = [np.random.default_rng(f.seed) for f in faults]
        self.gradient = np.stack([f.offset_gradient * np.linalg.qr(r.standard_normal((3, 3)))[0]
                                  for f, r in zip(faults, self._rngs, strict=True)])          # (n, 3, 3)
        self.position = np.broadcast_to(np.asarray(start, dtype=float), (n, 3)).copy()
        self.origin = self.position.copy()
        self.velocity = np.zeros((n, 3))
        self.target = self.position.copy()
        self.equilibrium = self.position.copy()    # the filtered target
        self.seen_x, self.seen_v = self.position.copy(), np.zeros((n, 3))  # controller's state
        self.command = np.zeros((n, 3))            # the controller's force on the arm [N]
        self.force = np.zeros((n, 3))              # contact force on the sensor [N]
        self.peak_force = np.zeros(n)              # largest contact force over the last step
        self.limit = float("inf")                  # a contact force above it counts [N]
        self.over_limit = np.zeros(n, dtype=int)   # control cycles with the force above it
        self.frozen = np.zeros(n, dtype=bool)      # a reflex stopped the arm
        self.time = 0.0                            # simulated time [s]
        self.jump_until = np.full(n, -1.0)         # activation transient until then [s]
        self._due = 0.0

    def contact(self, position: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Index of the platform under each sensor (-1: none) and the penetration below its
        true surface [m] (0 if none); as ``platform_under``, the first platform whose disc
        holds the sensor."""
        pos = self.position if position is None else np.asarray(position, dtype=float)
        gap = pos[:, None, :2] - self._centres_xy
        inside = np.einsum("npi,npi->np", gap, gap) <= self._radii2               # (n, P)
        idx = np.where(inside.any(axis=1), inside.argmax(axis=1), -1)
        top = self.centres[np.maximum(idx, 0), 2] + self.dz
        pen = np.where(idx >= 0, np.maximum(0.0, top - pos[:, 2]), 0.0)
        return idx, pen

    def _contact_force(self) -> np.ndarray:
        _, pen = self.contact()
        fz = np.where(pen > 0.0, np.maximum(0.0, self.kp * pen - self.dp * self.velocity[:, 2]),
                      0.0)
        out = np.zeros((self.n, 3))
        out[:, 2] = fz
        return out

    def control(self) -> np.ndarray:
        """One control cycle of the law (``ControlLaw`` steps 1-6); returns (and holds) the
        controller's force [N], (n, 3)."""
        law = self.law
        a, b, c = law.target_filter, law.state_filter, law.output_filter
        # a filter of weight 0 is the identity: skipped (the same numbers, fewer array passes)
        self.equilibrium = ((1.0 - a) * self.target + a * self.equilibrium) if a else \
            self.target.copy()
        if b:
            self.seen_x = (1.0 - b) * self.position + b * self.seen_x
            self.seen_v = (1.0 - b) * self.velocity + b * self.seen_v
        else:
            self.seen_x, self.seen_v = self.position.copy(), self.velocity.copy()
        goal = self.equilibrium
        if law.activation_jump_s > 0:
            jumping = (self.time < self.jump_until)[:, None]
            goal = goal + np.where(jumping, np.asarray(law.activation_jump), 0.0)
        err = goal - self.seen_x
        if law.error_clip != np.inf or law.lateral_error_clip not in (0.0, np.inf):
            clip = law.clip
            err = np.clip(err, -clip, clip)
        f = self.k * err - self.d * self.seen_v
        if c:
            f = (1.0 - c) * f + c * self.command
        step = f - self.command
        if law.max_force_step != np.inf:
            step = np.clip(step, -law.max_force_step, law.max_force_step)
        self.command = self.command + step
        return self.command

    def cycle(self) -> None:
        """One control cycle of ``1 / rate_hz`` s (one sample)."""
        h = self.h
        frozen = self.frozen.any()
        push = (np.where(self.frozen[:, None], 0.0, self.control()) if frozen
                else self.control()) + self.force + self.static
        if frozen:
            self.command[self.frozen] = 0.0
        if self._frictionless and not frozen:
            # no friction, nothing frozen: an axis sticks only at rest with no push at all
            stick = (np.abs(self.velocity) <= self._STICK) & (push == 0.0)
            if stick.any():
                acc = np.where(stick, 0.0, push / self.m[:, None])
                v0 = np.where(stick, 0.0, self.velocity)
            else:
                acc, v0 = push / self.m[:, None], self.velocity
            self.position = self.position + (v0 * h + 0.5 * acc * h * h)
            self.velocity = v0 + acc * h
        else:
            fc = self.fc[:, None]
            moving = np.abs(self.velocity) > self._STICK
            stick = (~moving & (np.abs(push) <= fc)) | self.frozen[:, None]
            direction = np.where(moving, np.sign(self.velocity), np.sign(push))
            acc = np.where(stick, 0.0, (push - fc * direction - self.fv[:, None] * self.velocity)
                           / self.m[:, None])
            v0 = np.where(stick, 0.0, self.velocity)
            v1 = v0 + acc * h
            stop = (fc > 0) & (v0 * v1 < 0)  # Coulomb friction stops an axis, never reverses it
            self.position = self.position + np.where(stop, 0.5 * v0 * h,
                                                     v0 * h + 0.5 * acc * h * h)
            self.velocity = np.where(stop, 0.0, v1)
        self.time += h
        self.force = self._contact_force()
        mag = np.linalg.norm(self.force, axis=1)
        self.peak_force = np.maximum(self.peak_force, mag)
        if self.limit != np.inf:
            self.over_limit += mag > self.limit

    def step(self, dt: float, sampled: bool = False) -> np.ndarray | None:
        """Advance ``dt`` [s] in whole control cycles (a remainder is carried to the next
        step); ``peak_force`` = largest contact force among them. ``sampled``: return what the
        robot reports at every cycle, (n, cycles, 3) [N] (``wrench`` per cycle, the full-rate
        stream), else None."""
        self._due += max(0.0, dt)
        self.peak_force = np.linalg.norm(self.force, axis=1)
        n = int(np.floor(self._due / self.h + 1e-9))
        self._due -= n * self.h
        out = np.empty((self.n, n, 3)) if sampled else None
        for j in range(n):
            self.cycle()
            if out is not None:
                out[:, j] = self._bias_read()
        if out is not None and n and np.any(self.noise > 0):
            out += self.noise[:, None, None] * np.stack([r.standard_normal((n, 3))
                                                         for r in self._rngs])
        return out

    def _bias_read(self) -> np.ndarray:
        """The reported force without the noise [N], (n, 3)."""
        return (self.force + self.static + self.offset + self.drift * self.time
                + np.einsum("nij,nj->ni", self.gradient, self.position - self.origin))

    def wrench(self) -> np.ndarray:
        """The external force each robot reports (base frame, + z where a contact pushes)
        [N], (n, 3): contact + static force + offset (with its configuration part and drift)
        + noise."""
        read = self._bias_read()
        if np.any(self.noise > 0):
            read = read + self.noise[:, None] * np.stack(
                [r.standard_normal(3) for r in self._rngs])
        return read


class ArmModel:
    """One mock arm in one world (``Worlds`` of one): the mock arm node runs it. ``position``,
    ``velocity``, ``target``, ``equilibrium``, ``command``, ``force`` are (3,) views of the
    world's state; units as ``Worlds``."""

    def __init__(self, scene: Workspace, start: np.ndarray, law: ControlLaw | None = None, *,
                 mass: float = 3.0, faults: Faults | None = None) -> None:
        self.law = law or ControlLaw(stiffness=1000.0)
        self.faults = faults or Faults()
        self.world = Worlds(scene, start, self.law, [self.faults], mass)
        self.scene = shift_surfaces(scene, self.faults.surface_offset)   # the true surfaces
        self.k, self.d, self.h = self.world.k, self.world.d, self.world.h

    def _get(name: str):   # noqa: N805 -- a property factory for the (3,) views
        return property(lambda self: getattr(self.world, name)[0],
                        lambda self, v: getattr(self.world, name).__setitem__(
                            0, np.asarray(v, dtype=float)))

    position, velocity, target = _get("position"), _get("velocity"), _get("target")
    equilibrium, command, force = _get("equilibrium"), _get("command"), _get("force")
    del _get

    @property
    def peak_force(self) -> float:
        """Largest contact force over the cycles of the last step [N]."""
        return float(self.world.peak_force[0])

    @property
    def frozen(self) -> bool:
        return bool(self.world.frozen[0])

    def contact(self, position: np.ndarray | None = None) -> tuple[Platform | None, float]:
        """Platform under the sensor and the penetration below its true surface [m]."""
        i, pen = platform_under(self.scene.platforms,
                                self.position if position is None else position)
        return (None, 0.0) if i is None else (self.scene.platforms[i], pen)

    def control(self) -> np.ndarray:
        return self.world.control()[0]

    def cycle(self) -> None:
        self.world.cycle()

    def step(self, dt: float) -> None:
        self.world.step(dt)

    def freeze(self) -> None:
        """A reflex: the arm stops where it is (brakes)."""
        self.world.frozen[0] = True
        self.world.velocity[0] = 0.0
        self.world.force = self.world._contact_force()

    def release(self) -> None:
        """Control is back: the target restarts at the current pose (CRISP's ``on_activate``
        sets it to the measured pose), the held force at zero, and the law's activation
        transient starts."""
        w = self.world
        w.frozen[0] = False
        w.force = w._contact_force()
        for name in ("target", "equilibrium", "seen_x"):
            getattr(w, name)[0] = w.position[0]
        w.seen_v[0] = 0.0
        w.command[0] = 0.0
        w.jump_until[0] = w.time + self.law.activation_jump_s

    def wrench(self) -> np.ndarray:
        """The external force the robot reports [N] (``Worlds.wrench``)."""
        return self.world.wrench()[0]

    def normal_force(self) -> float:
        """Contact normal force on the sensor [N] (>= 0; the truth, not the reading)."""
        return float(self.world.force[0, 2])


@dataclass
class WorldPress:
    """One press in one simulated world: the press's ``outcome``, the true contact normal
    force when it asked for the frame [N] (nan: it never did), the largest true contact force
    over every control cycle [N], the true surface z under the press [m], and the control
    cycles at which the true contact force was above ``max_force``."""

    outcome: PressOutcome
    true_force_n: float
    peak_force_n: float
    true_surface_z: float
    over_limit_samples: int = 0


#: [N] the gel image shows contact from this true normal force on (the GelSight Mini's
#: markers and shading move visibly at a fraction of a newton; assumed)
IMAGE_CONTACT_N = 0.3


class Camera:
    """The mock camera of ``press_in_worlds``: a frame every ``1 / fps`` s, in contact when the
    true normal force is at least ``IMAGE_CONTACT_N``, seen by the press one frame later (the
    stream's latency). ``burst(t, window_s)``: the in-contact frames ending at the newest seen
    frame, at most ``window_s`` old, consecutive (the capture's burst)."""

    def __init__(self, n: int, fps: float | None) -> None:
        self.period = None if not fps else 1.0 / fps
        self.next_t = 0.0
        self.frames: list[tuple[float, np.ndarray]] = []   # (stamp, in contact (n,))

    def update(self, t: float, force_z: np.ndarray) -> None:
        if self.period is None:
            return
        while self.next_t <= t + 1e-9:
            self.frames.append((self.next_t, force_z >= IMAGE_CONTACT_N))
            self.next_t += self.period
        del self.frames[:-64]

    def _seen(self, t: float) -> list[tuple[float, np.ndarray]]:
        return [f for f in self.frames if f[0] + self.period <= t + 1e-9]

    def contact(self, t: float, i: int) -> bool | None:
        if self.period is None:
            return None
        seen = self._seen(t)
        return bool(seen[-1][1][i]) if seen else False

    def burst(self, t: float, i: int, window_s: float) -> int:
        if self.period is None:
            return 1 << 30
        count = 0
        for stamp, flags in reversed(self._seen(t)):
            if t - stamp > window_s + 1e-9 or not flags[i]:
                break
            count += 1
        return count


def press_in_worlds(scene: Workspace, law: ControlLaw, faults: Sequence[Faults],
                    platform_ids: Sequence[str], *, start: np.ndarray | None = None,
                    mass: Sequence[float] | float = 3.0, stiffness: float | None = None,
                    rate_hz: float = 50.0, t_max: float = 120.0,
                    camera_fps: float | None = None,
                    surface_hints: Sequence[float | None] | None = None) -> list[WorldPress]:
    """Press ``platform_ids[i]`` in world ``faults[i]`` for every i, the press ticked at
    ``rate_hz`` [Hz] on what the robot reports (pose, and every wrench sample since the last
    tick: the full-rate stream), assuming the controller stiffness ``stiffness`` (default the
    law's requested one, as the motion node does), from ``start`` (default 0.1 m above the
    first platform's approach point; (n, 3) one per world). ``camera_fps``: a camera
    (``Camera``) streams its contact verdict to the press and the capture waits for a burst
    of ``capture_frames`` in-contact frames within ``capture_window_s`` (None: no camera, the
    capture is immediate). ``surface_hints[i]``: the surface an earlier press found (None:
    the scene's)."""
    plats = [next(p for p in scene.platforms if p.id == pid) for pid in platform_ids]
    if start is None:
        p0 = np.asarray(scene.platforms[0].position, dtype=float)
        start = p0 + [0.0, 0.0, scene.press.approach_height + 0.1]
    w = Worlds(scene, start, law, faults, mass)
    w.limit = scene.press.max_force
    k = law.stiffness if stiffness is None else stiffness
    hints = surface_hints or [None] * w.n
    ctrls = [PressController(scene, p, w.position[i], 0.0, stiffness=k, period_s=1.0 / rate_hz,
                             surface_hint=hints[i])
             for i, p in enumerate(plats)]
    cam = Camera(w.n, camera_fps)
    s = scene.press
    true_force = np.full(w.n, np.nan)
    peak = np.zeros(w.n)
    t, dt = 0.0, 1.0 / rate_hz
    samples = w.wrench()[:, None, :]
    while t < t_max and not all(c.done for c in ctrls):
        read = samples[:, -1]
        # every world's samples as (normal, magnitude), once per tick: (n, cycles, 2)
        pairs = np.stack([samples[:, :, 2], np.linalg.norm(samples, axis=2)], axis=2)
        cam.update(t, w.force[:, 2])
        for i, c in enumerate(ctrls):
            if c.done:
                continue
            w.target[i] = c.step(t, w.position[i], float(read[i, 2]),
                                 float(pairs[i, -1, 1]), samples=pairs[i],
                                 contact=cam.contact(t, i))
            if c.capture_requested and cam.burst(t, i, s.capture_window_s) >= s.capture_frames:
                true_force[i] = w.force[i, 2]
                c.captured(True, "", t)
        got = w.step(dt, sampled=True)
        if got is not None and got.shape[1]:
            samples = got
        peak = np.maximum(peak, w.peak_force)
        t += dt
    for c in ctrls:
        if not c.done:
            c.abort(f"simulation ended at t_max {t_max} s in phase {c.phase}", t)
    return [WorldPress(c.outcome(), float(true_force[i]), float(peak[i]),
                       float(plats[i].position[2] + w.dz[i]), int(w.over_limit[i]))
            for i, c in enumerate(ctrls)]
