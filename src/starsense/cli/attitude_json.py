"""The attitude of a solved frame in the JSON lines of ``solve`` and ``track``.

One convention, stated here and in the commands' help: the attitude is the rotation that takes
ICRS vectors into the camera frame (:mod:`starsense.geometry.attitude`: +z along the boresight,
+x towards increasing column, +y towards increasing row).

``quaternion_xyzw``
    That rotation as a unit quaternion, scalar LAST ``[x, y, z, w]`` (the order of
    ``scipy.spatial.transform.Rotation.from_quat``), with ``w >= 0``.
``rotation_matrix``
    The same rotation as a 3 x 3 matrix, rows first: ``v_camera = M @ v_icrs``.
``sigma_arcsec``
    The 1-sigma attitude error about the camera axes, arcsec, by name: ``x`` and ``y``
    (cross-boresight) and ``roll`` (about the boresight, z).
"""

from __future__ import annotations

__all__ = ["SIGMA_AXES", "attitude_fields", "with_attitude"]

#: the names of the camera axes of ``sigma_arcsec``, in the order of ``Solution.sigma_rad``
SIGMA_AXES = ("x", "y", "roll")


def attitude_fields(solution) -> dict:
    """Return the attitude fields of a solution's JSON line.

    Parameters
    ----------
    solution : starsense.solve.Solution
        A frame's solution (solved or not).

    Returns
    -------
    dict
        ``quaternion_xyzw`` (list of 4 float, scalar last, ICRS -> camera, ``w >= 0``),
        ``rotation_matrix`` (3 lists of 3 float) and ``sigma_arcsec`` (``{"x", "y", "roll"}``,
        arcsec); each None when the solution has no such value.
    """
    rot = solution.rotation
    quat = matrix = None
    if rot is not None:
        q = rot.as_quat()  # scalar last
        q = -q if q[3] < 0 else q  # q and -q are one rotation: the one with w >= 0
        quat = [float(v) for v in q]
        matrix = [[float(v) for v in row] for row in rot.as_matrix()]
    sigma = solution.sigma_arcsec
    labelled = None if sigma is None else dict(zip(SIGMA_AXES, map(float, sigma), strict=True))
    return {"quaternion_xyzw": quat, "rotation_matrix": matrix, "sigma_arcsec": labelled}


def with_attitude(payload: dict, solution) -> dict:
    """Return ``payload`` with the attitude fields of ``solution`` (:func:`attitude_fields`).

    The fields follow ``roll_deg`` (or end the object when it has none); ``sigma_arcsec``
    replaces the unlabelled list of :meth:`starsense.solve.Solution.to_dict` in its place.
    """
    fields = attitude_fields(solution)
    out: dict = {}
    for key, value in payload.items():
        if key == "sigma_arcsec":
            out[key] = fields["sigma_arcsec"]
            continue
        out[key] = value
        if key == "roll_deg":
            out["quaternion_xyzw"] = fields["quaternion_xyzw"]
            out["rotation_matrix"] = fields["rotation_matrix"]
    for key, value in fields.items():
        out.setdefault(key, value)
    return out
