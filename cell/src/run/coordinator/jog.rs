//! Manual control (seed 001 §5.3.2): one robot position and one mandrel move, sent together.

use super::*;

impl Coordinator<'_> {
    /// Manual control (seed 001 §5.3.2, §5.4): one robot position and one mandrel instruction
    /// sent together, each confirmed. `relative` positions are added to the robot's position now.
    /// The wrist quaternion of `p` is the App. A pitch and roll in the arm's vertical plane: the
    /// five-axis arm has no wrist yaw (§4.1.1), so the base yaw that turns that plane to the
    /// target, `atan2(y, x)`, is put in front of it (a pose out of the plane would be refused,
    /// error 9). Returns the robot's position (mm) and the indexer's counter (steps) afterwards.
    pub fn jog(
        &mut self,
        speeds: (asea_protocol::Speed, asea_protocol::Speed),
        mut p: Positioning,
        relative: bool,
        mandrel: Option<MandrelMove>,
        reach: Reach,
    ) -> Result<([f64; 3], i64), Stopped> {
        let r = (|| -> Result<([f64; 3], i64), Step> {
            self.check()?;
            let counter = self.dev.mandrel.attach()?;
            self.ready_robot()?;
            let mut target = p.pose.xyz_mm();
            if relative {
                let here = self.dev.robot.position_mm()?;
                target = [
                    here[0] + target[0],
                    here[1] + target[1],
                    here[2] + target[2],
                ];
                p.pose =
                    asea_protocol::Pose::from_mm(target, p.pose.q.wxyz()).map_err(|source| {
                        Fault::JogTelegram {
                            what: "the relative move leaves the telegram's range",
                            source: Box::new(source),
                        }
                    })?;
                p.flags.reference = asea_protocol::Reference::Absolute;
            }
            let yaw = nalgebra::UnitQuaternion::from_axis_angle(
                &nalgebra::Vector3::z_axis(),
                target[1].atan2(target[0]),
            );
            let [w, x, y, z] = p.pose.q.wxyz();
            let q = yaw
                * nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
            p.pose =
                asea_protocol::Pose::from_mm(target, [q.w, q.i, q.j, q.k]).map_err(|source| {
                    Fault::JogTelegram {
                        what: "the jog's pose",
                        source: Box::new(source),
                    }
                })?;
            if !reach.holds(target) || !reach.arm_takes(p.pose.xyz_mm(), p.pose.q.wxyz()) {
                return Err(Fault::OutOfReach { eye_mm: target }.into());
            }
            self.dev.robot.set_speeds(speeds.0, speeds.1)?;
            let end = counter + mandrel.map_or(0, |m| m.steps);
            let moving = match mandrel {
                Some(m) => self.mandrel_start(m, counter, end, false)?,
                None => false,
            };
            self.robot_to(p, target)?;
            if moving {
                self.mandrel_finish(end)?;
            }
            Ok((self.dev.robot.position_mm()?, end))
        })();
        r.map_err(|Step::Halt(halt)| Stopped {
            halt,
            item: 0,
            path: String::new(),
            segments_done: 0,
            stop_errors: self.stop_devices(),
        })
    }
}
