"""Drawing each joint's servo from a profile's ``[uncertainty]`` (domain randomisation)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import ProfileError
from ..units import JOINT_NAMES
from ..validation import check_range
from .profiles import load_profile
from .servo import _BOUNDS, _OPEN_LOW, MAX_SIGMAS, UNCERTAIN_FIELDS, ArmLike


def draw_servo_deltas(
    profile: ArmLike,
    rng: np.random.Generator,
    sigmas: float = 1.0,
    joints: tuple[str, ...] = JOINT_NAMES,
) -> dict[str, dict[str, float]]:
    """One draw of each joint's servo from ``profile``'s ``[uncertainty]``: for each joint
    (in ``joints``' order) and each field of the table (in :data:`UNCERTAIN_FIELDS`' order), the
    drawn value minus the profile's own, at the profile's supply (``ArmProfile.joint``). Each
    field is drawn independently per joint as the value plus ``sigmas`` × its standard deviation
    × a standard normal number cut at ±:data:`MAX_SIGMAS`, kept inside the field's bounds. No
    table, or ``sigmas`` = 0: an empty dict per joint, and nothing drawn from ``rng``.

    Raises:
        ProfileError: ``sigmas`` outside 0 to :data:`MAX_SIGMAS`.
    """
    prof = load_profile(profile)
    k = check_range(sigmas, "actuator sigmas", low=0.0, high=MAX_SIGMAS, error=ProfileError)
    names = [n for n in UNCERTAIN_FIELDS if prof.uncertainty.get(n, 0.0) > 0]
    if not names or k == 0:
        return {j: {} for j in joints}
    z = np.clip(rng.standard_normal((len(joints), len(names))), -MAX_SIGMAS, MAX_SIGMAS)
    out: dict[str, dict[str, float]] = {}
    for i, joint in enumerate(joints):
        raw = prof.joint(joint, scaled=False)
        values = {}
        for f, name in enumerate(names):
            low, high, _ = _BOUNDS[name]
            v = getattr(raw, name) + k * prof.uncertainty[name] * z[i, f]
            floor = low + 1e-9 if name in _OPEN_LOW else low
            values[name] = float(np.clip(v, floor, high))
        drawn = replace(prof, joints={joint: {**prof.joints.get(joint, {}), **values}})
        new, old = drawn.joint(joint), prof.joint(joint)
        out[joint] = {n: getattr(new, n) - getattr(old, n) for n in names}
    return out
