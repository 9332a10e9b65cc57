"""The FK round trip of :mod:`ik5r.core.reference_kernel`: the returned angles put back through
the forward kinematics, a branch flagged UNREACHABLE where its tool point or approach misses.

Work arrays are (4, m) over the four branches; the order of the float operations is the
reference's (see :mod:`ik5r.core.reference_kernel`), so the flags are the same bits wherever the
check is called from.
"""

from __future__ import annotations

import numpy as np

from . import status as st


def sincos(x):
    """(sin x, cos x) of float64 angles by the tangent of the half angle, t = tan(x / 2):
    sin x = 2 t / (1 + t^2), cos x = (1 - t^2) / (1 + t^2). Absolute error a few 1e-16 for
    |x| < 2 pi (checked against np.sin / np.cos in tests/test_reference.py).

    numpy's float64 sin and cos are scalar libm calls (about 15 ns each); its tan is vectorised
    (about 3 ns), so this is about 5x cheaper than np.sin plus np.cos.
    """
    t = np.multiply(x, 0.5)
    np.tan(t, out=t)
    t2 = t * t
    inv = t2 + 1.0
    np.reciprocal(inv, out=inv)
    t *= inv
    t *= 2.0
    np.subtract(1.0, t2, out=t2)
    t2 *= inv
    return t, t2


def _branch_trig(Q, offsets, sense):
    """sin and cos of the returned angles, (13, m): q1 of branch 0 (the back shoulder's q1 + pi:
    cos/sin negated, rounding differences far below the tolerance), q2, q3, q4 of every branch."""
    X = np.empty((13, Q.shape[2]))
    X[0] = Q[0, 0]
    X[1:5] = Q[:, 1]
    X[5:9] = Q[:, 2]
    X[9:13] = Q[:, 3]
    for j, rows in enumerate((slice(0, 1), slice(1, 5), slice(5, 9), slice(9, 13))):
        if sense[j] < 0:      # the readings of a reversed joint back to its DH angle
            np.negative(X[rows], out=X[rows])
    if np.any(offsets != 0):
        X[0] += offsets[0]
        X[1:5] += offsets[1]
        X[5:9] += offsets[2]
        X[9:13] += offsets[3]
    with np.errstate(over="ignore", invalid="ignore"):
        return sincos(X)


def _tool_plane(arm, cs, sn):
    """The tool point in the arm plane (r, y) and the approach's plane angle (cp, sp) of each
    branch, from the trig of :func:`_branch_trig`."""
    a1, a2, a3, a4, _ = arm.a
    d5 = arm.d[4]
    c2, s2, c3, s3, c4, s4 = cs[1:5], sn[1:5], cs[5:9], sn[5:9], cs[9:13], sn[9:13]
    c23 = c2 * c3
    c23 -= s2 * s3
    s23 = s2 * c3
    s23 += c2 * s3
    cp = c23 * c4
    cp -= s23 * s4
    sp = s23 * c4
    sp += c23 * s4
    r = a2 * c2
    r += a1
    r += a3 * c23
    r += a4 * cp
    r -= d5 * sp
    y = a2 * s2
    y += a3 * s23
    y += a4 * sp
    y += d5 * cp
    return r, y, cp, sp


def confirm(arm, Q, S, P, cphi, sphi, c1_in, s1_in, offsets, tol_cm, tol_dir):
    """FK of the returned angles: flag UNREACHABLE where the tool point or the approach misses.

    Q (4, 5, m) angles, S (4, m) status (updated), P (3, m) target tool points; cphi, sphi: the
    projected approach (cos phi_front, -sin phi_front); c1_in, s1_in: the IK's arm plane.
    """
    px, py, pz = P
    sn, cs = _branch_trig(Q, offsets, arm.sense)
    c1, s1 = cs[0], sn[0]
    r, y, cp, sp = _tool_plane(arm, cs, sn)
    r[2:] *= -1.0                 # back shoulder: (r cos(q1 + pi), r sin(q1 + pi)) = -r (c1, s1)
    ex = r * c1
    ex -= px
    ey = r * s1
    ey -= py
    ez = pz + y
    ez -= arm.d[0]                # -(d1 - y - pz)
    err = ex * ex
    err += ey * ey
    err += ez * ez
    miss = err > tol_cm * tol_cm
    # approach a = (-sp cos q1, -sp sin q1, -cp) against the projected target
    # (-sin phi_f c1, -sin phi_f s1, -cos phi) = (sphi c1_in, sphi s1_in, -cphi)
    sp[:2] *= -1.0                # front: -sp; back: -sp * (-1)
    ex = sp * c1
    ex -= sphi * c1_in
    ey = sp * s1
    ey -= sphi * s1_in
    ez = cp - cphi                # (-cp) - (-cphi), squared
    err = ex * ex
    err += ey * ey
    err += ez * ez
    miss |= err > tol_dir * tol_dir
    harmless = st.SINGULAR_ELBOW | st.SINGULAR_BASE | st.BAD_ORIENTATION
    miss &= (S & ~harmless) == 0
    if miss.any():
        S[miss] |= st.UNREACHABLE
