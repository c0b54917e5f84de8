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
///
/// ```
/// use volcomp::axes::Axes;
/// use volcomp::gcode::{Frame, Pose};
/// use volcomp::kinematics::{Geometry, Kinematics};
/// use volcomp::toolpath::{joints_of, pose_of};
///
/// let kinematics = Kinematics::new(Geometry::default(), 100.0);
/// // A tool-tip target: the tip in part coordinates, A and C as given.
/// let target = Pose::in_frame(Frame::Part, Axes::xyzac(10.0, 0.0, 5.0, 30.0, 45.0));
/// let joints = joints_of(&kinematics, &target);
/// assert_eq!((joints.a, joints.c), (30.0, 45.0));
/// let back = pose_of(&kinematics, Frame::Part, &joints);
/// assert!(back.axes().xyz_distance(&target.axes()) < 1e-9);
/// ```
///
/// A programmed value is not joints: it becomes joints through this function
/// (or, for values that are machine coordinates, `Joints::new`).
///
/// ```compile_fail
/// use volcomp::axes::{Axes, Joints};
/// let programmed = Axes::xyzac(10.0, 0.0, 5.0, 30.0, 45.0);
/// let joints: Joints = programmed;
/// ```
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gcode::{Feed, Motion, MotionKind};
    use crate::kinematics::Geometry;

    fn kinematics() -> Kinematics {
        let geometry = Geometry {
            x_rot_point: 20.0,
            y_rot_point: -10.0,
            z_rot_point: -50.0,
            y_offset: 5.0,
            z_offset: 3.0,
        };
        Kinematics::new(geometry, 120.0)
    }

    fn motion(frame: Frame, machine_coordinates: bool) -> Motion {
        Motion {
            kind: MotionKind::Linear,
            frame,
            machine_coordinates,
            start: Axes::default(),
            end: Axes::xyzac(10.0, 20.0, 30.0, 40.0, 50.0),
            feed: Feed::PerMinute(100.0),
            duration_min: 0.0,
        }
    }

    #[test]
    fn a_g53_target_is_joints_in_a_part_frame_program() {
        let kin = kinematics();
        let m = motion(Frame::Part, true);
        assert_eq!(m.target_frame(), Frame::Joint);
        assert_eq!(m.end_pose(), Pose::Joint(Joints::new(m.end)));
        assert_eq!(joints_of(&kin, &m.end_pose()).axes(), m.end);
    }

    #[test]
    fn a_part_frame_target_goes_through_the_kinematics_and_back() {
        let kin = kinematics();
        let m = motion(Frame::Part, false);
        let pose = m.end_pose();
        assert_eq!(pose.frame(), Frame::Part);
        let joints = joints_of(&kin, &pose);
        // The nominal tip of the joints is the programmed tip; the rotary
        // joints are the programmed ones.
        let tip = kin.nominal_tip(&joints);
        assert!(crate::vec3::dist(tip, m.end.xyz()) < 1e-9);
        assert_eq!((joints.a, joints.c), (m.end.a, m.end.c));
        assert!(joints.xyz_distance(&m.end) > 1.0, "the frames differ here");
        let back = pose_of(&kin, Frame::Part, &joints);
        assert!(back.axes().xyz_distance(&m.end) < 1e-9);
        assert_eq!(pose_of(&kin, Frame::Joint, &joints), Pose::Joint(joints));
    }
}
