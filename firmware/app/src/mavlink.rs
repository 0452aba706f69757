//! MAVLink for autopilots: a `HEARTBEAT` a second and a `LANDING_TARGET` for every frame with a
//! pose, what ArduPilot's and PX4's precision landing read from a companion camera.
//!
//! The messages are MAVLink 2 frames of the `common` dialect, built by the `mavlink` crate
//! (no_std; its `LANDING_TARGET` carries the MAVLink 2 extension fields `x`, `y`, `z`, `q`,
//! `type` and `position_valid`). A board writes the bytes of [`Mavlink::heartbeat`] and
//! [`Mavlink::landing_target`] to the UART wired to the autopilot's telemetry port.
//!
//! # The landing target
//!
//! A frame's pose ([`PoseRecord`]) maps target-plane points to the camera,
//! `X_cam = R X + t`, with the target's corner `(0, 0)` at its origin (the convention of
//! [`camgeom::target`]). The landing target is the target's centre,
//!
//! ```text
//! c = R (w/2, h/2, 0)ᵀ + t            (camera frame: x right, y down, z along the optical axis)
//! ```
//!
//! and, with `R_bc` the camera's mounting (camera to body FRD, [`MavlinkConfig::new`]):
//!
//! | field | value |
//! |---|---|
//! | `frame` | `MAV_FRAME_BODY_FRD` |
//! | `x`, `y`, `z` | `R_bc c`, metres (the target's unit) |
//! | `q` | `R_bc R` as a quaternion `(w, x, y, z)`: the target's orientation in the body frame |
//! | `distance` | `‖c‖` |
//! | `angle_x`, `angle_y` | `atan2(c_x, c_z)`, `atan2(c_y, c_z)`: the offset from the image centre, radians |
//! | `size_x`, `size_y` | `2 atan(w / 2‖c‖)`, `2 atan(h / 2‖c‖)`: the target's angular size |
//! | `type` | `LANDING_TARGET_TYPE_VISION_FIDUCIAL` |
//! | `position_valid` | 1 |
//!
//! A pose that is not finite, or a target behind the camera, gives no message.

use camgeom::nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use camgeom::{Error, Result};
use mavlink::dialects::common::{
    HEARTBEAT_DATA, LANDING_TARGET_DATA, LandingTargetType, MavAutopilot, MavBool, MavFrame,
    MavModeFlag, MavState, MavType,
};
use mavlink::{MAVLinkV2MessageRaw, MavHeader, MessageData};

use crate::report::PoseRecord;

/// `MAV_COMP_ID_CAMERA`: the component id a camera takes when nothing else is configured.
pub const COMPONENT_CAMERA: u8 = 100;

/// How far from orthonormal a mounting rotation may be (each entry of `RᵀR - I`).
const ROTATION_TOLERANCE: f32 = 1e-3;

/// How the board talks MAVLink, checked once: its system and component ids, the landing
/// target's number, and the camera's mounting on the vehicle.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MavlinkConfig {
    system_id: u8,
    component_id: u8,
    target_num: u8,
    /// Body FRD from camera, row-major.
    camera_to_body: [[f32; 3]; 3],
}

impl MavlinkConfig {
    /// The camera looking straight down with the top of the image toward the nose: camera
    /// `x` (right) is body `y` (right), camera `y` (down the image) is body `-x` (aft),
    /// camera `z` (the optical axis) is body `z` (down).
    pub const DOWNWARD_TOP_FORWARD: [[f32; 3]; 3] =
        [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]];

    /// Checks the configuration: `camera_to_body` (`R_bc`, row-major) must be a rotation
    /// (orthonormal to 1e-3, determinant +1).
    ///
    /// Errors: [`Error::InvalidParameter`]`("camera_to_body")`.
    pub fn new(
        system_id: u8,
        component_id: u8,
        target_num: u8,
        camera_to_body: [[f32; 3]; 3],
    ) -> Result<Self> {
        let r = matrix(&camera_to_body);
        let off = r.transpose() * r - Matrix3::identity();
        if !off.iter().all(|v| v.abs() <= ROTATION_TOLERANCE) || r.determinant() <= 0.0 {
            return Err(Error::InvalidParameter("camera_to_body"));
        }
        Ok(Self {
            system_id,
            component_id,
            target_num,
            camera_to_body,
        })
    }

    /// The system id the messages carry.
    pub fn system_id(&self) -> u8 {
        self.system_id
    }
}

impl Default for MavlinkConfig {
    /// System 1 (the vehicle's, as ArduPilot and PX4 expect of a companion), component
    /// [`COMPONENT_CAMERA`], target 0, [`Self::DOWNWARD_TOP_FORWARD`].
    fn default() -> Self {
        Self {
            system_id: 1,
            component_id: COMPONENT_CAMERA,
            target_num: 0,
            camera_to_body: Self::DOWNWARD_TOP_FORWARD,
        }
    }
}

fn matrix(m: &[[f32; 3]; 3]) -> Matrix3<f32> {
    let [a, b, c] = *m;
    Matrix3::new(a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2])
}

/// The MAVLink sender: numbers the messages and builds each in its own buffer.
pub struct Mavlink {
    config: MavlinkConfig,
    camera_to_body: Rotation3<f32>,
    seq: u8,
    raw: MAVLinkV2MessageRaw,
}

impl Mavlink {
    /// The longest message this sends (a `LANDING_TARGET` with every extension field), bytes.
    pub const MAX_LEN: usize = 12 + LANDING_TARGET_DATA::ENCODED_LEN + 2;

    /// A sender for `config`, its sequence at 0.
    pub fn new(config: MavlinkConfig) -> Self {
        Self {
            camera_to_body: Rotation3::from_matrix_unchecked(matrix(&config.camera_to_body)),
            config,
            seq: 0,
            raw: MAVLinkV2MessageRaw::new(),
        }
    }

    fn header(&mut self) -> MavHeader {
        let h = MavHeader {
            system_id: u32::from(self.config.system_id),
            component_id: self.config.component_id,
            sequence: self.seq,
        };
        self.seq = self.seq.wrapping_add(1);
        h
    }

    fn frame(&mut self, data: &impl MessageData) -> &[u8] {
        let header = self.header();
        self.raw.serialize_message_data(header, data);
        self.raw.raw_bytes()
    }

    /// A `HEARTBEAT` (a camera, no autopilot, active): send one a second, or the autopilot
    /// forgets the component.
    pub fn heartbeat(&mut self) -> &[u8] {
        let data = HEARTBEAT_DATA {
            custom_mode: 0,
            mavtype: MavType::MAV_TYPE_CAMERA,
            autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
            base_mode: MavModeFlag::empty(),
            system_status: MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        };
        self.frame(&data)
    }

    /// The `LANDING_TARGET` of a frame taken at `time_usec` (microseconds since boot) whose
    /// target, `size = [w, h]`, was seen at `pose` (see the module's table); `None` for a pose
    /// that is not finite or a target centre not in front of the camera.
    pub fn landing_target(
        &mut self,
        time_usec: u64,
        pose: &PoseRecord,
        size: [f32; 2],
    ) -> Option<&[u8]> {
        let data = landing_target(&self.config, &self.camera_to_body, time_usec, pose, size)?;
        Some(self.frame(&data))
    }
}

/// The message's fields, or `None` (see [`Mavlink::landing_target`]).
fn landing_target(
    config: &MavlinkConfig,
    camera_to_body: &Rotation3<f32>,
    time_usec: u64,
    pose: &PoseRecord,
    [w, h]: [f32; 2],
) -> Option<LANDING_TARGET_DATA> {
    let finite = |v: &[f32]| v.iter().all(|x| x.is_finite());
    if !finite(&pose.t) || !finite(&pose.r) || !finite(&[w, h]) {
        return None;
    }
    let rotation = Rotation3::new(Vector3::from(pose.r));
    let c = rotation * Vector3::new(0.5 * w, 0.5 * h, 0.0) + Vector3::from(pose.t);
    let distance = c.norm();
    if !(c.z > 0.0 && distance.is_finite()) {
        return None;
    }
    let body = camera_to_body * c;
    let q = UnitQuaternion::from_rotation_matrix(&(camera_to_body * rotation));
    let angular = |s: f32| 2.0 * libm::atanf(0.5 * s / distance);
    Some(LANDING_TARGET_DATA {
        time_usec,
        angle_x: libm::atan2f(c.x, c.z),
        angle_y: libm::atan2f(c.y, c.z),
        distance,
        size_x: angular(w),
        size_y: angular(h),
        target_num: config.target_num,
        frame: MavFrame::MAV_FRAME_BODY_FRD,
        x: body.x,
        y: body.y,
        z: body.z,
        q: [q.w, q.i, q.j, q.k],
        mavtype: LandingTargetType::LANDING_TARGET_TYPE_VISION_FIDUCIAL,
        position_valid: MavBool::MAV_BOOL_TRUE,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose(t: [f32; 3], r: [f32; 3]) -> PoseRecord {
        PoseRecord { t, r, rms_px: 0.1 }
    }

    #[test]
    fn mounting_must_be_a_rotation() {
        let ok = MavlinkConfig::new(1, COMPONENT_CAMERA, 0, MavlinkConfig::DOWNWARD_TOP_FORWARD);
        assert!(ok.is_ok());
        let mirror = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]];
        let scaled = [[2.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let nan = [[f32::NAN, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        for m in [mirror, scaled, nan] {
            assert_eq!(
                MavlinkConfig::new(1, 1, 0, m),
                Err(Error::InvalidParameter("camera_to_body"))
            );
        }
    }

    #[test]
    fn centre_below_a_downward_camera() {
        let cfg = MavlinkConfig::default();
        let r = Rotation3::from_matrix_unchecked(matrix(&cfg.camera_to_body));
        // A 0.2 m square, 2 m down the optical axis, facing the camera; its centre 0.1 m to
        // the image's right of the axis: corner (0, 0) at (0.0, -0.1, 2.0).
        let d = landing_target(&cfg, &r, 7, &pose([0.0, -0.1, 2.0], [0.0; 3]), [0.2, 0.2]).unwrap();
        let c = [0.1f32, 0.0, 2.0];
        let norm = (c[0] * c[0] + c[2] * c[2]).sqrt();
        assert!((d.distance - norm).abs() < 1e-6);
        assert!((d.angle_x - libm::atan2f(0.1, 2.0)).abs() < 1e-6);
        assert!(d.angle_y.abs() < 1e-6);
        // Image right is the body's right: body (x, y, z) = (0, 0.1, 2).
        assert!(d.x.abs() < 1e-6 && (d.y - 0.1).abs() < 1e-6 && (d.z - 2.0).abs() < 1e-6);
        // The target's axes are the camera's, so its orientation is the mounting's.
        let q = UnitQuaternion::from_rotation_matrix(&r);
        for (a, b) in d.q.iter().zip([q.w, q.i, q.j, q.k]) {
            assert!((a - b).abs() < 1e-6);
        }
        assert_eq!((d.position_valid, d.time_usec), (MavBool::MAV_BOOL_TRUE, 7));
        assert_eq!(d.frame, MavFrame::MAV_FRAME_BODY_FRD);
    }

    #[test]
    fn no_message_without_a_usable_pose() {
        let mut m = Mavlink::new(MavlinkConfig::default());
        let behind = pose([0.0, 0.0, -1.0], [0.0; 3]);
        assert!(m.landing_target(0, &behind, [0.2, 0.2]).is_none());
        let nan = pose([f32::NAN, 0.0, 1.0], [0.0; 3]);
        assert!(m.landing_target(0, &nan, [0.2, 0.2]).is_none());
        let inf = pose([0.0, 0.0, 1.0], [f32::INFINITY, 0.0, 0.0]);
        assert!(m.landing_target(0, &inf, [0.2, 0.2]).is_none());
    }

    #[test]
    fn frames_are_mavlink_2_numbered_in_order() {
        let mut m = Mavlink::new(MavlinkConfig::default());
        let hb = m.heartbeat().to_vec();
        assert_eq!(hb.first(), Some(&0xFD));
        // Header: STX, len, incompat, compat, seq, sysid, compid, msgid (3 bytes).
        assert_eq!((hb[4], hb[5], hb[6], hb[7]), (0, 1, COMPONENT_CAMERA, 0));
        let lt = m
            .landing_target(1, &pose([0.0, 0.0, 1.0], [0.1, 0.2, 0.3]), [0.1, 0.1])
            .unwrap()
            .to_vec();
        assert_eq!((lt[0], lt[4], lt[7]), (0xFD, 1, 149));
        assert!(lt.len() <= Mavlink::MAX_LEN);
    }
}
