"""Active Brownian motion in SI units: a sphere of radius R swimming at speed v along a heading n
that diffuses on the unit sphere, in a fluid of viscosity eta at temperature T (the standard model
of a microswimmer; Volpe, Gigan & Volpe, Am. J. Phys. 82, 659 (2014)).

Units throughout: lengths in um, times in s, concentrations in nM (1 nM = 0.6022 molecules per
um^3), diffusion coefficients in um^2/s, rates in 1/s, viscosity in mPa s, temperature in K.

Per step ``dt_s`` (overdamped Langevin, Euler-Maruyama):
    position += v n dt + sqrt(2 D_T dt) xi        xi: three standard normals
    n        <- n cos(theta) + u sin(theta)       u: a random direction perpendicular to n
with theta Rayleigh-distributed, its scale chosen so that E[cos theta] = exp(-2 D_R dt) exactly:
each step's rotation is isotropic about n, so the heading correlation after k steps is
<n(k dt) . n(0)> = exp(-2 D_R k dt) for any dt, and |n| stays 1.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray
from scipy.optimize import brentq
from scipy.special import dawsn

from nanonav.engine.compiled import inlined, inlined_callable
from nanonav.engine.contacts import CellList, first_within, pushed_out, relist
from nanonav.engine.dynamics.lattice import reflect, segment_hit
from nanonav.engine.state import KernelParams, Swarm, World

# Stokes-Einstein(-Debye) lives with the schema, which fills D_T and D_R in from it.
from nanonav.scenario import BOLTZMANN_J_K as BOLTZMANN_J_K
from nanonav.scenario import MOLECULES_PER_UM3_PER_NM as MOLECULES_PER_UM3_PER_NM
from nanonav.scenario import stokes_einstein_debye_s as stokes_einstein_debye_s
from nanonav.scenario import stokes_einstein_um2_s as stokes_einstein_um2_s

# A robot pushed out of one robot into another is pushed out again, this many times at most.
CONTACT_PASSES = 4

# Rayleigh(sigma) rotation angles: E[cos theta] = 1 - 2 x F(x), x = sigma / sqrt(2), F Dawson's
# integral. It falls from 1 to 0 as x grows to about 0.9241, the largest step this allows.
_LARGEST_X = float(brentq(lambda x: 1.0 - 2.0 * x * dawsn(x), 0.5, 1.5))


def persistence_length_um(swim_speed_um_s: float, rotational_diffusion: float) -> float:
    """How far a swimmer goes before it forgets its heading: v tau_R, with tau_R = 1 / (2 D_R)
    the decay time of <n(t) . n(0)> in three dimensions."""
    return swim_speed_um_s / (2.0 * rotational_diffusion)


def peclet_translational(swim_speed_um_s: float, radius_um: float, diffusion: float) -> float:
    """v R / D_T: swimming against translational diffusion over one body radius."""
    return swim_speed_um_s * radius_um / diffusion


def peclet_rotational(
    swim_speed_um_s: float, radius_um: float, rotational_diffusion: float
) -> float:
    """v / (R D_R): body radii swum in the time the heading takes to turn by a radian."""
    return swim_speed_um_s / (radius_um * rotational_diffusion)


def heading_correlation(rotational_diffusion: float, lag_s: float) -> float:
    """<n(t) . n(0)> of a heading diffusing on the sphere: exp(-2 D_R t)."""
    return math.exp(-2.0 * rotational_diffusion * lag_s)


def mean_squared_displacement_um2(
    diffusion: float, swim_speed_um_s: float, rotational_diffusion: float, lag_s: float
) -> float:
    """The active Brownian particle's MSD in three dimensions:
    6 D_T t + (v^2 / D_R) [t - (1 - exp(-2 D_R t)) / (2 D_R)]."""
    t = lag_s
    active = 0.0
    if swim_speed_um_s and rotational_diffusion > 0.0:
        d_r = rotational_diffusion
        active = swim_speed_um_s**2 / d_r * (t - (1.0 - math.exp(-2.0 * d_r * t)) / (2.0 * d_r))
    elif swim_speed_um_s:
        active = (swim_speed_um_s * t) ** 2  # no rotational diffusion: straight on
    return 6.0 * diffusion * t + active


def heading_kick_scale(rotational_diffusion: float, dt_s: float) -> float:
    """The Rayleigh scale sigma of one step's rotation angle, such that E[cos theta] =
    exp(-2 D_R dt). Any step has one (the scale grows toward about 1.31 as the step forgets
    the heading entirely); the scenario's own bound keeps D_R dt small."""
    if rotational_diffusion < 0.0 or dt_s <= 0.0:
        raise ValueError("rotational diffusion must be >= 0 and dt_s > 0")
    target = math.exp(-2.0 * rotational_diffusion * dt_s)
    if target >= 1.0:
        return 0.0

    def gap(x: float) -> float:
        return 1.0 - 2.0 * x * float(dawsn(x)) - target

    if gap(_LARGEST_X) >= 0.0:  # the heading forgets itself within the step
        return _LARGEST_X * math.sqrt(2.0)
    return float(brentq(gap, 0.0, _LARGEST_X, xtol=1e-15)) * math.sqrt(2.0)


def berg_purcell_relative_error(
    molecule_diffusion_um2_s: float, sensor_radius_um: float, concentration_nm: float, time_s: float
) -> float:
    """The relative error of one reading of a concentration by a sensor at its physical limit:
    delta c / c = 1 / sqrt(pi D a c tau), for a perfectly absorbing sphere of radius a reading for
    a time tau molecules that diffuse with D at concentration c (molecules per um^3) (Berg &
    Purcell, Biophys. J. 20, 193 (1977); in this form, Bialek & Setayeshgar, PNAS 102, 10040
    (2005), eq. 1). Infinite where nothing is there to count."""
    molecules = concentration_nm * MOLECULES_PER_UM3_PER_NM
    counted = math.pi * molecule_diffusion_um2_s * sensor_radius_um * molecules * time_s
    return math.inf if counted <= 0.0 else 1.0 / math.sqrt(counted)


# The integral over one receptor patch of the unit sphere (the sixth of it nearer one axis's way
# than any other's) of the outward normal's component along that axis: the patch's shadow on
# the plane across the axis, where 2 y^2 + z^2 < 1 and y^2 + 2 z^2 < 1, whose area is
# 2 sqrt(2) atan(1 / sqrt(2)) ~ 1.741 (a hemisphere's shadow is pi)
PATCH_NORMAL_INTEGRAL = 2.0 * math.sqrt(2.0) * math.atan(1.0 / math.sqrt(2.0))
RECEPTOR_PATCHES = 6


def absorbed_fractions(
    receptors: int | None, receptor_radius_um: float, radius_um: float
) -> tuple[float, float]:
    """What a sphere of radius a covered with N receptors of radius s takes in, as fractions of
    a perfect absorber's (None receptors: the perfect absorber itself, 1 and 1).

    The total: N s / (N s + pi a) of Smoluchowski's 4 pi D a c (Berg & Purcell, Biophys. J.
    20, 193 (1977), eq. 8). The gradient's part: a linear gradient g adds 3 D g cos(theta) to a
    perfect absorber's inward flux density D c / a (theta from g's direction); a surface that
    absorbs at a uniform rate kappa takes in x / (1 + x) of the first and x / (2 + x) of the
    second, x = kappa a / D (Collins & Kimball, J. Colloid Sci. 4, 425 (1949), the flux's
    l = 0 and l = 1 terms), and x = N s / (pi a) gives Berg and Purcell's total: the receptors
    are taken as that uniform rate, so that the gradient is read with the same receptors."""
    if receptors is None:
        return 1.0, 1.0
    x = receptors * receptor_radius_um / (math.pi * radius_um)
    return x / (1.0 + x), x / (2.0 + x)


def patch_rates(
    molecule_diffusion_um2_s: float, radius_um: float, total: float, gradient: float
) -> tuple[float, float]:
    """What one receptor patch (a sixth of the body) takes in a second, on average: per nM of
    the concentration at the body's centre, and per nM/um of the gradient along the patch's
    axis (its sign: toward the patch), for a body that takes in ``total`` and ``gradient`` of a
    perfect absorber's (``absorbed_fractions``). A perfect absorber's flux density is
    D (c / a + 3 g cos(theta)) (``absorbed_fractions``): over a patch, D c / a times its area
    4 pi a^2 / 6, and 3 D g a^2 times ``PATCH_NORMAL_INTEGRAL``."""
    d, a = molecule_diffusion_um2_s, radius_um
    per_nm = d * a * (4.0 * math.pi / RECEPTOR_PATCHES) * total * MOLECULES_PER_UM3_PER_NM
    per_gradient = 3.0 * d * a * a * PATCH_NORMAL_INTEGRAL * gradient * MOLECULES_PER_UM3_PER_NM
    return per_nm, per_gradient


@inlined
def _tangent_basis(
    nx: float, ny: float, nz: float
) -> tuple[float, float, float, float, float, float]:
    """Two unit vectors perpendicular to the unit vector n and to each other."""
    ax, ay, az = (0.0, 1.0, 0.0) if abs(nx) > 0.9 else (1.0, 0.0, 0.0)
    dot = ax * nx + ay * ny + az * nz
    ex = ax - dot * nx
    ey = ay - dot * ny
    ez = az - dot * nz
    norm = math.sqrt(ex * ex + ey * ey + ez * ez)
    ex /= norm
    ey /= norm
    ez /= norm
    return ex, ey, ez, ny * ez - nz * ey, nz * ex - nx * ez, nx * ey - ny * ex


@inlined_callable
def _unit(x: float, y: float, z: float) -> tuple[float, float, float]:
    norm = math.sqrt(x * x + y * y + z * z)
    return x / norm, y / norm, z / norm


@inlined
def _turned_across(
    nx: float, ny: float, nz: float, ex: float, ey: float, ez: float, fx: float, fy: float,
    fz: float, a: float, b: float, size: float, angle: float,
) -> tuple[float, float, float]:  # fmt: skip
    """The unit vector n turned by ``angle`` toward a e + b f, of length ``size`` (e and f
    unit vectors across n and each other)."""
    c = math.cos(angle)
    s = math.sin(angle) / size
    return _unit(
        c * nx + s * (a * ex + b * fx),
        c * ny + s * (a * ey + b * fy),
        c * nz + s * (a * ez + b * fz),
    )


@inlined_callable
def diffuse_heading(
    rng: np.random.Generator, nx: float, ny: float, nz: float, sigma: float
) -> tuple[float, float, float]:
    """One step of rotational diffusion: n cos(theta) + u sin(theta), where sigma (g1, g2) in the
    tangent plane gives the direction u and the angle theta (Rayleigh with scale sigma)."""
    if sigma == 0.0:
        return nx, ny, nz
    ex, ey, ez, fx, fy, fz = _tangent_basis(nx, ny, nz)
    g1 = rng.standard_normal()
    g2 = rng.standard_normal()
    g = math.sqrt(g1 * g1 + g2 * g2)
    if g == 0.0:
        return nx, ny, nz
    return _turned_across(nx, ny, nz, ex, ey, ez, fx, fy, fz, g1, g2, g, sigma * g)


@inlined_callable
def turn_toward(
    nx: float, ny: float, nz: float, tx: float, ty: float, tz: float, largest: float
) -> tuple[float, float, float]:
    """The unit heading n turned toward the direction t by its angle to it, at most ``largest``
    radians, in the plane of the two (n unchanged where t is zero)."""
    t = math.sqrt(tx * tx + ty * ty + tz * tz)
    if t == 0.0 or largest <= 0.0:
        return nx, ny, nz
    tx /= t
    ty /= t
    tz /= t
    cosine = min(1.0, max(-1.0, nx * tx + ny * ty + nz * tz))
    angle = math.acos(cosine)
    if angle <= largest:
        return tx, ty, tz
    ux = tx - cosine * nx
    uy = ty - cosine * ny
    uz = tz - cosine * nz
    u = math.sqrt(ux * ux + uy * uy + uz * uz)
    if u < 1e-12:  # t is opposite n: every way round is as short
        ux, uy, uz, _, _, _ = _tangent_basis(nx, ny, nz)
    else:
        ux /= u
        uy /= u
        uz /= u
    c = math.cos(largest)
    s = math.sin(largest)
    return _unit(c * nx + s * ux, c * ny + s * uy, c * nz + s * uz)


@inlined_callable
def body_frame(
    nx: float, ny: float, nz: float, sx: float, sy: float, sz: float
) -> tuple[float, float, float, float, float, float]:
    """A robot's two body axes across its heading n: ``side``, the last side axis s carried
    along as the heading turns (s with its part along n taken out; the heading's tangent
    basis where s is zero or nearly along n, as at the start or after a tumble), and ``up``,
    n x side. Carried so, the axes turn with the body and a turn held over steps keeps its
    sense (the body's roll about n is not modelled)."""
    dot = sx * nx + sy * ny + sz * nz
    ex = sx - dot * nx
    ey = sy - dot * ny
    ez = sz - dot * nz
    norm = math.sqrt(ex * ex + ey * ey + ez * ez)
    if norm < 1e-3:
        ex, ey, ez, _, _, _ = _tangent_basis(nx, ny, nz)
    else:
        ex /= norm
        ey /= norm
        ez /= norm
    return ex, ey, ez, ny * ez - nz * ey, nz * ex - nx * ez, nx * ey - ny * ex


@inlined_callable
def turn_in_body(
    nx: float, ny: float, nz: float, sx: float, sy: float, sz: float, u_side: float,
    u_up: float, largest: float,
) -> tuple[float, float, float]:  # fmt: skip
    """The unit heading n turned toward ``u_side`` side + ``u_up`` up (the body axes of
    ``body_frame``, s its side axis) by ``largest`` radians times the turn's size, |u| capped
    at 1: a continuous steering command, as a fraction of the largest turn a step allows
    (n unchanged where u is zero)."""
    size = math.sqrt(u_side * u_side + u_up * u_up)
    if size == 0.0 or largest <= 0.0:
        return nx, ny, nz
    ex, ey, ez, fx, fy, fz = body_frame(nx, ny, nz, sx, sy, sz)
    angle = largest * min(1.0, size)
    return _turned_across(nx, ny, nz, ex, ey, ez, fx, fy, fz, u_side, u_up, size, angle)


@njit(cache=True, error_model="numpy")
def swim(
    rng: np.random.Generator,
    pos: NDArray[np.float64],
    heading: NDArray[np.float64],
    active: NDArray[np.bool_],
    swim_speed_um_s: float,
    diffusion_um2_s: float,
    heading_sigma: float,
    dt_s: float,
) -> None:
    """Advance every active robot one step in free space: swim along its heading, diffuse, and
    let the heading diffuse (the module docstring gives the scheme)."""
    jiggle = math.sqrt(2.0 * diffusion_um2_s * dt_s)
    stride = swim_speed_um_s * dt_s
    for i in range(pos.shape[0]):
        if not active[i]:
            continue
        nx = heading[i, 0]
        ny = heading[i, 1]
        nz = heading[i, 2]
        pos[i, 0] += stride * nx + jiggle * rng.standard_normal()
        pos[i, 1] += stride * ny + jiggle * rng.standard_normal()
        pos[i, 2] += stride * nz + jiggle * rng.standard_normal()
        nx, ny, nz = diffuse_heading(rng, nx, ny, nz, heading_sigma)
        heading[i, 0] = nx
        heading[i, 1] = ny
        heading[i, 2] = nz


@inlined_callable
def read_concentration(rng: np.random.Generator, concentration: float, relative_sd: float) -> float:
    """One reading of a true concentration with the given relative error: a gamma draw, whose
    mean is the concentration and whose sd is ``relative_sd`` times it, never negative."""
    if relative_sd <= 0.0:
        return max(concentration, 0.0)
    return read_counted(rng, concentration, 1.0 / (relative_sd * relative_sd))


@inlined
def read_counted(rng: np.random.Generator, concentration: float, molecules: float) -> float:
    """A reading of a concentration from ``molecules`` counted: a gamma draw of that shape, mean
    the concentration and relative sd 1 / sqrt(molecules) (Berg-Purcell's, when ``molecules``
    is pi D a c tau), never negative."""
    if concentration <= 0.0 or molecules <= 0.0:
        return 0.0
    return rng.gamma(molecules, concentration / molecules)


@inlined
def free_at(p: KernelParams, w: World, x: float, y: float, z: float) -> bool:
    """Whether a robot's centre may be at (x, y, z): inside the walls (if any) and clear of
    every obstacle."""
    if p.walls and (abs(x) > p.half or abs(y) > p.half or abs(z) > p.half):
        return False
    return segment_hit(w.obstacles, p.obstacle_radius, x, y, z, x, y, z) < 0


@inlined
def move_robot(
    p: KernelParams, rng: np.random.Generator, w: World, s: Swarm, i: int,
    px: float, py: float, pz: float,
) -> tuple[float, float, float, bool]:  # fmt: skip
    """One overdamped step of robot ``i`` at p: swim along its heading and jiggle, reflected by
    the walls. A step that brings its surface into an obstacle's is a contact (counted as a
    collision): the robot stops at the surface, the part of the step into the obstacle undone
    and the rest kept (``pushed_out``), so it slides round the obstacle at a speed that does
    not depend on dt; a step that passes through one, or whose contact point is not free, is
    refused (the robot stays). Then its heading diffuses. Returns where it ends and whether it
    touched an obstacle."""
    hx = s.heading[i, 0]
    hy = s.heading[i, 1]
    hz = s.heading[i, 2]
    nx = px + p.speed * hx + p.jiggle * rng.standard_normal()
    ny = py + p.speed * hy + p.jiggle * rng.standard_normal()
    nz = pz + p.speed * hz + p.jiggle * rng.standard_normal()
    if p.walls:
        nx = reflect(nx, p.half)
        ny = reflect(ny, p.half)
        nz = reflect(nz, p.half)
    hit = segment_hit(w.obstacles, p.obstacle_radius, px, py, pz, nx, ny, nz)
    blocked = hit >= 0
    if blocked:
        s.collisions[i] += 1
        nx, ny, nz, inside = pushed_out(
            w.obstacles[hit, 0], w.obstacles[hit, 1], w.obstacles[hit, 2], p.obstacle_radius,
            nx, ny, nz,
        )  # fmt: skip
        if not inside or not free_at(p, w, nx, ny, nz):
            nx = px
            ny = py
            nz = pz
    dx = nx - px
    dy = ny - py
    dz = nz - pz
    s.path_length[i] += math.sqrt(dx * dx + dy * dy + dz * dz)
    s.pos[i, 0] = nx
    s.pos[i, 1] = ny
    s.pos[i, 2] = nz
    hx, hy, hz = diffuse_heading(rng, hx, hy, hz, p.heading_sigma)
    s.heading[i, 0] = hx
    s.heading[i, 1] = hy
    s.heading[i, 2] = hz
    return nx, ny, nz, blocked


@inlined
def make_way(
    p: KernelParams, w: World, grid: CellList, everyone: NDArray[np.bool_], s: Swarm, i: int,
    px: float, py: float, pz: float,
) -> tuple[float, float, float, bool]:  # fmt: skip
    """Robot ``i`` moved from p to where ``s.pos`` has it, with the other robots hard spheres
    ``p.contact`` apart: one now closer is a bump, and the robot stops at contact with it
    (``pushed_out``), then with the next it then overlaps, and so on (``CONTACT_PASSES`` at
    most, so that a robot squeezed between two slides along both); or at p, where that finds
    no free point (of robots, obstacles, the walls). Lists it where it ends. Returns where it
    ends and whether it bumped."""
    x = s.pos[i, 0]
    y = s.pos[i, 1]
    z = s.pos[i, 2]
    bumped = False
    free = False
    for _ in range(CONTACT_PASSES):
        j = first_within(grid, s.pos, everyone, x, y, z, p.contact, i)
        if j < 0:
            free = not bumped or free_at(p, w, x, y, z)
            break
        bumped = True
        x, y, z, inside = pushed_out(s.pos[j, 0], s.pos[j, 1], s.pos[j, 2], p.contact, x, y, z)
        if not inside:
            break
    if not free:
        x = px
        y = py
        z = pz
    else:
        relist(grid, i, x, y, z)
    s.pos[i, 0] = x
    s.pos[i, 1] = y
    s.pos[i, 2] = z
    return x, y, z, bumped
