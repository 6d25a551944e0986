"""Forward kinematics by pinocchio, the independent reference the written recordings are checked against."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin


class PinocchioRobot:
    def __init__(self, urdf: Path) -> None:
        self.model = pin.buildModelFromUrdf(str(urdf))
        self.data = self.model.createData()

    def link_poses(self, joint_values: dict[str, float]) -> dict[str, np.ndarray]:
        """Pose of every link in the URDF root link's frame, for the given joint values (radians / metres)."""
        q = pin.neutral(self.model)
        for joint_id in range(1, self.model.njoints):
            name = self.model.names[joint_id]
            joint = self.model.joints[joint_id]
            if name not in joint_values:
                continue
            value = joint_values[name]
            if joint.nq == 2 and joint.nv == 1:  # continuous joint: pinocchio stores (cos, sin)
                q[joint.idx_q : joint.idx_q + 2] = [np.cos(value), np.sin(value)]
            else:
                assert joint.nq == 1, f"{name}: only 1-dof joints are used in these tests"
                q[joint.idx_q] = value
        pin.forwardKinematics(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        return {
            frame.name: self.data.oMf[index].homogeneous.copy()
            for index, frame in enumerate(self.model.frames)
            if frame.type == pin.FrameType.BODY
        }

    def limits(self, joint: str) -> tuple[float, float]:
        joint_id = self.model.getJointId(joint)
        index = self.model.joints[joint_id].idx_q
        return float(self.model.lowerPositionLimit[index]), float(self.model.upperPositionLimit[index])
