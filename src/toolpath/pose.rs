//! The one conversion between a program's poses and machine joints.
//!
//! A motion's target says its frame ([`Pose`], from `Motion::end_pose` and
//! friends: G53 targets are joints whatever the program's frame); a part-frame
//! target (the tool tip in part coordinates, as a tool-tip control reads it)
//! becomes joints through the nominal kinematics the control itself uses, with
//! the rotary joints (and U V W) as given. Every command that needs the joints
//! of a target, or writes joints back as a target, goes through these two.
use crate::axes::{Axes, Joints};
use crate::gcode::{Frame, Pose};
use crate::kinematics::Kinematics;

/// The joints of `pose` (nominal kinematics; the rotary joints as given).
#[inline]
pub fn joints_of(kinematics: &Kinematics, pose: &Pose) -> Joints {
    match pose {
        Pose::Joint(joints) => *joints,
        Pose::Part(part) => Joints::new(kinematics.nominal_joints_for_tip(part.xyz(), part)),
    }
}

/// The pose in `frame` of `joints` (inverse of [`joints_of`]): a part-frame pose
/// is the nominal tool tip in part coordinates with the same rotary joints.
#[inline]
pub fn pose_of(kinematics: &Kinematics, frame: Frame, joints: &Joints) -> Pose {
    match frame {
        Frame::Joint => Pose::Joint(*joints),
        Frame::Part => {
            let tip = kinematics.nominal_tip(joints);
            Pose::Part(Axes {
                x: tip[0],
                y: tip[1],
                z: tip[2],
                ..joints.axes()
            })
        }
    }
}
