"""``python -m stage1_pose.pretrained RUN``: make the stage-1 run ``RUN`` the package's default pose model."""

from __future__ import annotations

import sys

from dancesynth.core.checkpoint import export_checkpoint
from dancesynth.core.errors import DancesynthError
from stage1_pose.pretrained import DEFAULT_POSE_MODEL, LOCAL_ENTRIES


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print("usage: python -m stage1_pose.pretrained RUN_DIR", file=sys.stderr)
        return 2
    try:
        export_checkpoint(argv[0], DEFAULT_POSE_MODEL, "stage1", drop=LOCAL_ENTRIES)
    except DancesynthError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    print(f"wrote {DEFAULT_POSE_MODEL}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
