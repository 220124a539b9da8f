"""Version-checked decoding of rdslam's rdslam.pose_t for Python LCM subscribers.

LCM prefixes every message with a fingerprint of its type's fields (8 bytes, big-endian),
and the generated decode() refuses any other fingerprint with a bare "Decode error". This
module names the versions instead, so a subscriber and a publisher from different rdslam
versions fail with an error that says what to update:

    import sys
    sys.path += ["BUILD/lcmtypes/python", "RDSLAM/tools/lcm"]  # lcm-gen's output, this file
    import lcm, rdslam_msgs

    def on_pose(channel, data):
        m = rdslam_msgs.decode_pose(data)  # rdslam.pose_t, or raises VersionMismatch
        if m.state in (m.STATE_TRACKING, m.STATE_RELOCALIZED):
            ...  # m.map_epoch: which map; m.covariance: 6x6 row-major, see the .lcm

The Python types come from lcm-gen on lcmtypes/*.lcm (the build puts them in
BUILD/lcmtypes/python; the package installs the .lcm files in /usr/share/rdslam/lcmtypes and
this file in /usr/share/rdslam/python). This file must come from the same rdslam as those
types; decode_pose() checks that too.
"""

import struct

from rdslam import pose_t

# The fingerprint (first 8 bytes) of every published version of rdslam.pose_t.
#  1: utime, seq, position, orientation, covariance (always -1), quality, inliers, state,
#     latency_us (rdslam before the map epoch and the pose covariance).
#  2: a leading `version`, `map_epoch`, the covariance of the final eq. (1) refinement.
# A new version adds its fingerprint here (tests/integration/test_run_lcm.cpp checks that the
# generated type's fingerprint is listed under its VERSION).
POSE_FINGERPRINTS = {
    1: 0x9E8A9BC1E75BDC76,
    2: 0xEC7B43F336AA2521,
}


class VersionMismatch(ValueError):
    """A message of another rdslam.pose_t version than the one this subscriber was built for."""

    def __init__(self, text, message_version, expected_version):
        ValueError.__init__(self, text)
        self.message_version = message_version  # None when it cannot be told
        self.expected_version = expected_version


def _fingerprint(data):
    return struct.unpack(">Q", data[:8])[0]


def message_version(data):
    """The rdslam.pose_t version of an encoded message, or None if it is none of them."""
    if len(data) < 8:
        return None
    fp = _fingerprint(data)
    for v, known in POSE_FINGERPRINTS.items():
        if known == fp:
            return v
    if len(data) >= 12:  # every version from 2 on starts with `int32_t version` (bytes 8..11)
        v = struct.unpack(">i", data[8:12])[0]
        if v > max(POSE_FINGERPRINTS):  # a later version: its leading field says which
            return v
    return None


def _expected():
    expected_fp = _fingerprint(pose_t._get_packed_fingerprint())
    if POSE_FINGERPRINTS.get(pose_t.VERSION) != expected_fp:
        raise RuntimeError(
            "rdslam_msgs.py does not match the generated rdslam.pose_t (VERSION %d, fingerprint "
            "0x%016x): use the rdslam_msgs.py of the rdslam the types were generated from"
            % (pose_t.VERSION, expected_fp))
    return pose_t.VERSION, expected_fp


def decode_pose(data):
    """Decodes an rdslam.pose_t; raises VersionMismatch naming both versions on a mismatch."""
    expected_version, expected_fp = _expected()
    data = bytes(data)
    if len(data) >= 8 and _fingerprint(data) == expected_fp:
        return pose_t.decode(data)
    got_fp = _fingerprint(data) if len(data) >= 8 else None
    got = message_version(data)
    head = "rdslam.pose_t version mismatch: message fingerprint %s, expected 0x%016x (version %d)" % (
        "0x%016x" % got_fp if got_fp is not None else "(message shorter than 8 bytes)",
        expected_fp, expected_version)
    if got is None:
        text = head + ": not any rdslam.pose_t version (another type on this channel?)"
    elif got < expected_version:
        text = head + (
            ": the message is version %d, from an older rdslam than this subscriber's types; "
            "update rdslam on the publishing side, or decode it with types generated from that "
            "rdslam's lcmtypes/rdslam_pose_t.lcm" % got)
    else:
        text = head + (
            ": the message is version %d, from a newer rdslam; regenerate this subscriber's "
            "types (lcm-gen) from the publisher's lcmtypes/rdslam_pose_t.lcm and take its "
            "tools/lcm/rdslam_msgs.py" % got)
    raise VersionMismatch(text, got, expected_version)
