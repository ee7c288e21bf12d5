"""A plain statement of the blade solver (paper V.A, eqs 14-32): float64, one cell at a time,
one joint at a time, no scratch buffers, no folding of constants. Slow on purpose; the fast
solver (grass_addon/solver.py) must match it (tests/core/test_solver_reference.py).

The model is the fast solver's (its module doc says why each step reads the paper as it does):
the wind loads act on the equilibrium estimate E, which relaxes towards the reconfigured statics;
the bend moves towards E by the smooth update of eqs 25-27 or, above n_boundary of eq 28, swings
about it by the damped oscillator of eqs 29-32 with aerodynamic damping.
"""

from __future__ import annotations

import math

import numpy as np
from windgrass.grass_addon import blade
from windgrass.grass_addon import solver as fast

RHO_AIR = fast.RHO_AIR


class ReferenceCell:
    """The representative blade of one cell and its state (float64)."""

    def __init__(self, layout, params, c: int):
        b = params.blade
        n = layout.segments
        self.n = n
        self.length = float(layout.cell_length[c])
        self.seg = self.length / n  # l_length
        self.facing = float(layout.cell_facing[c])
        self.rest_tilt = layout.cell_rest_tilt[c].astype(np.float64)
        # eqs 1 and 5, per joint (blade.joint_stiffness: mu * n / REFERENCE_SEGMENTS)
        per_joint = n / blade.REFERENCE_SEGMENTS
        self.mu_base = [float(layout.cell_root_stiffness[c]) * per_joint / (self.seg * i + b.stiffness_offset)
                        for i in range(n)]
        self.k = b.nonlinear_stiffness * per_joint ** 2  # eq 23's k per joint
        self.stiffen_limit = fast.STIFFEN_LIMIT / per_joint
        self.width = [float(layout.cell_width[c]) * (1.0 - (1.0 - b.tip_width) * (j + 0.5) / n) for j in range(n)]
        self.inertia = [b.density * ((n - j) * self.seg) ** 3 for j in range(n)]  # M_grass of eq 29
        self.gamma, self.twist_ratio = b.response_torque, b.twist_stiffness
        self.alpha, self.beta = b.damping_mass, b.damping_stiffness  # eq 31
        self.air_damping = b.air_damping  # the share of the drag's damping taken
        self.boundary_k, self.boundary_lambda = b.boundary_k, b.boundary_lambda  # eq 28
        ratio = max(1.0, self.twist_ratio)
        self.omega2 = [(mu + self.k * self.stiffen_limit) / inertia * ratio
                       for mu, inertia in zip(self.mu_base, self.inertia)]
        self.damp = [self.alpha + self.beta * w2 for w2 in self.omega2]
        self.bend = np.zeros((n, 2))
        self.vel = np.zeros((n, 2))
        self.twist = np.zeros(n)
        self.twist_vel = np.zeros(n)
        self.eq = np.zeros((n, 2))  # E, the equilibrium estimate the loads act on

    # -------------------------------------------------------------------------- eqs 14-20

    def forcing(self, wind: np.ndarray):
        """Bend torque M_i (eq 18 with the statics of eqs 3-4), twist torque M_t,i (eq 20), the
        wind direction, speed, the rest face's angle to the wind, and per segment F_j, cos|T_j|."""
        n = self.n
        v2 = float(wind @ wind)
        speed = max(math.sqrt(v2), 1e-6)
        w_hat = wind / speed
        face = np.array([math.cos(self.facing), math.sin(self.facing)])
        dot = face @ wind
        cross = face[0] * wind[1] - face[1] * wind[0]
        delta0 = math.atan2(cross * dot, dot * dot)  # rest face normal (a line) to the wind line
        force, twist_force, cos_tilt = [], [], []
        total = np.zeros(2)
        for j in range(n):
            total = total + self.eq[j]
            T = self.rest_tilt[j] * face + total  # absolute tilt vector of segment j
            tilt = math.hypot(T[0], T[1])
            cos_phi = (T @ w_hat) / max(tilt, fast.EPS) * math.sin(tilt)  # eq 16: axis . wind
            sin_phi = math.sqrt(max(1.0 - cos_phi * cos_phi, 0.0))
            area = RHO_AIR * v2 * self.seg * self.width[j]  # v^2 rho l_length l_width
            force.append(area * sin_phi)  # eq 17
            twist_force.append(area * abs(cos_phi * math.sin(tilt)) * self.seg)  # eqs 19-20 (lever l sin)
            cos_tilt.append(math.cos(tilt))
        # eq 18: joint i carries every segment above it at its vertical lever (to the segment's centre)
        bend_torque = []
        for i in range(n):
            m = 0.0
            for j in range(i, n):
                lever = sum(self.seg * cos_tilt[k] for k in range(i, j)) + 0.5 * self.seg * cos_tilt[j]
                m += force[j] * lever
            bend_torque.append(m)
        twist_torque = [sum(twist_force[i:]) for i in range(n)]
        return bend_torque, twist_torque, w_hat, speed, delta0, force, cos_tilt

    def aero_q(self, force, cos_tilt, i: int) -> float:
        """Q_i = sum_{j>=i} F_j h_ij^2 (h_ij: the vertical lever from joint i to segment j's
        centre): the aerodynamic damping torque of a swinging joint is 2 Q_i theta' / |v|."""
        q = 0.0
        for j in range(i, self.n):
            lever = sum(self.seg * cos_tilt[k] for k in range(i, j)) + 0.5 * self.seg * cos_tilt[j]
            q += force[j] * lever * lever
        return q

    # -------------------------------------------------------------------------- one step

    def step(self, wind: np.ndarray, dt: float, substeps: int) -> None:
        n, h = self.n, dt / substeps
        visible = (2.0 * math.pi / (fast.FRAMES_PER_SWAY * dt)) ** 2
        bend_torque, twist_torque, w_hat, speed, delta0, force, cos_tilt = self.forcing(wind)

        # eqs 22-23: mu_i(t) = mu_i^base + k |theta_i(t - dt)|; eq 21/24: equilibrium M / mu
        mu = [self.mu_base[i] + self.k * min(math.hypot(*self.bend[i]), self.stiffen_limit) for i in range(n)]
        e = [min(max(bend_torque[i] / mu[i], -fast.BEND_LIMIT), fast.BEND_LIMIT) for i in range(n)]
        # twist equilibrium: each joint turns the face by M_t / (K_t / 2 + M_t) of what is left
        eq_twist, left = [], delta0
        for i in range(n):
            turn = twist_torque[i] / (0.5 * self.twist_ratio * mu[i] + twist_torque[i]) * left
            eq_twist.append(turn)
            left -= turn
        eq_twist = [min(max(t, -fast.TWIST_LIMIT), fast.TWIST_LIMIT) for t in eq_twist]
        # E relaxes towards the statics: one under-relaxed fixed-point step per frame
        relax = min(1.0, dt / fast.REFERENCE_DT) / (1.0 + fast.RELAX_GAIN * sum(abs(x) for x in e))
        self.eq = self.eq * (1.0 - relax) + np.outer(np.array(e) * relax, w_hat)

        # eq 28: n_boundary from the swing amplitude about the equilibrium
        swing = 0.0
        for i in range(n):
            gap = self.eq[i] - self.bend[i]
            w2 = mu[i] / self.inertia[i]
            swing += math.sqrt(gap @ gap + (self.vel[i] @ self.vel[i]) / w2) + abs(eq_twist[i] - self.twist[i])
        exponent = min(-self.boundary_lambda * (swing / (2.0 * n) - self.boundary_k), math.log(n) + 1.0)
        n_boundary = min(n * math.exp(exponent), n)

        for i in range(n):
            allowed = (h * self.damp[i] <= 1.0 and h * h * self.omega2[i] + 2.0 * h * self.damp[i] <= 2.0
                       and self.omega2[i] <= visible)
            y = self.eq[i] - self.bend[i]  # the joint's gap to its equilibrium
            yt = eq_twist[i] - self.twist[i]
            if i + 1 > n_boundary and allowed:
                # eqs 29-32 about the equilibrium, symplectic Euler, with aerodynamic damping
                # taken implicitly: I theta'' = -K y-ish terms, C = alpha I + beta K (eq 31)
                stiffness_per_inertia = mu[i] / self.inertia[i]
                aero = 2.0 * self.air_damping * self.aero_q(force, cos_tilt, i) / speed / self.inertia[i]
                rc = 1.0 / (1.0 + h * aero)
                q = h * stiffness_per_inertia * rc
                p = rc * (1.0 - h * self.alpha) - self.beta * q
                qt = h * stiffness_per_inertia * self.twist_ratio
                pt = 1.0 - h * self.alpha - self.beta * qt
                vel, vt = self.vel[i].copy(), self.twist_vel[i]
                for _ in range(substeps):
                    vel = p * vel + q * y
                    y = y - h * vel
                    vt = pt * vt + qt * yt
                    yt = yt - h * vt
                self.vel[i] = vel
                self.twist_vel[i] = vt
                self.bend[i] = np.clip(self.eq[i] - y, -fast.BEND_LIMIT, fast.BEND_LIMIT)
                self.twist[i] = min(max(eq_twist[i] - yt, -fast.TWIST_LIMIT), fast.TWIST_LIMIT)
            else:
                # eqs 25-27 as a rate: theta += (theta_eq - theta) f, f = 1 - exp(-(M / gamma) dt / dt_ref)
                # with M = mu max(gap, 0.1 rad); joints too fast to show a sway follow at once
                quasi = fast.QUASI_RATE if self.omega2[i] > visible else 0.0
                rate = mu[i] * dt / (self.gamma * fast.REFERENCE_DT) + quasi
                f = -math.expm1(-max(math.hypot(*y), fast.SMOOTH_MIN_ANGLE) * rate)
                ft = -math.expm1(-max(abs(yt), fast.SMOOTH_MIN_ANGLE) * rate * self.twist_ratio)
                self.bend[i] = self.bend[i] + f * y
                self.vel[i] = f * y / dt
                self.twist[i] += ft * yt
                self.twist_vel[i] = ft * yt / dt
