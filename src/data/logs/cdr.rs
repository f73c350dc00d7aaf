//! `sensor_msgs/msg/JointState` in ROS 2's CDR serialisation (the bytes of
//! a bag message), decoded by the `cdr-encoding` crate.
//!
//! A serialised message is a 4-byte encapsulation header (`00 01`: CDR
//! little endian, `00 00`: big endian; two option bytes) and the CDR body,
//! aligned from the body's start:
//!
//! ```text
//! std_msgs/Header header        builtin_interfaces/Time stamp (int32 sec, uint32 nanosec), string frame_id
//! string[]  name
//! float64[] position
//! float64[] velocity
//! float64[] effort
//! ```
//!
//! Sequence and string lengths are never trusted beyond the bytes present:
//! the decoder reads element by element and fails at the end of the input,
//! so a corrupt length cannot make it allocate more than the message holds.

use serde::Deserialize;

/// `builtin_interfaces/msg/Time`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize)]
pub struct Time {
    /// Seconds since the epoch.
    pub sec: i32,
    /// Nanoseconds within the second (0..10⁹).
    pub nanosec: u32,
}

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize, serde::Serialize)]
pub struct Header {
    /// When the joints were sampled.
    pub stamp: Time,
    /// Frame (unused here).
    pub frame_id: String,
}

/// `sensor_msgs/msg/JointState`: per named joint, position (rad or m),
/// velocity (rad/s or m/s) and effort (N·m or N); each array empty or as
/// long as `name`.
#[derive(Debug, Clone, PartialEq, Deserialize, serde::Serialize)]
pub struct JointState {
    /// Header with the sampling time stamp.
    pub header: Header,
    /// Joint names.
    pub name: Vec<String>,
    /// Positions.
    pub position: Vec<f64>,
    /// Velocities.
    pub velocity: Vec<f64>,
    /// Efforts.
    pub effort: Vec<f64>,
}

impl Time {
    /// Nanoseconds since the epoch; an error when `nanosec` ≥ 10⁹.
    pub fn nanoseconds(&self) -> Result<i64, String> {
        if self.nanosec >= 1_000_000_000 {
            return Err(format!("header.stamp.nanosec = {} is not below 10⁹", self.nanosec));
        }
        Ok(i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec))
    }
}

/// The ROS 2 message type decoded here.
pub const JOINT_STATE: &str = "sensor_msgs/msg/JointState";

/// Decodes one serialised JointState (encapsulation header included).
/// Errors are text naming what is wrong (the caller adds file, topic and
/// message index).
pub fn decode_joint_state(bytes: &[u8]) -> Result<JointState, String> {
    if bytes.len() < 4 {
        return Err(format!("{} bytes: shorter than the 4-byte CDR encapsulation header", bytes.len()));
    }
    let body = &bytes[4..];
    let decoded = match (bytes[0], bytes[1]) {
        (0, 1) => cdr_encoding::from_bytes::<JointState, byteorder::LittleEndian>(body),
        (0, 0) => cdr_encoding::from_bytes::<JointState, byteorder::BigEndian>(body),
        (a, b) => {
            return Err(format!(
                "encapsulation {a:02x} {b:02x}: expected plain CDR (00 01 little endian, 00 00 big endian) as ROS 2 writes it"
            ))
        }
    };
    let (msg, _) = decoded.map_err(|e| format!("not a sensor_msgs/msg/JointState in CDR ({} bytes): {e}", bytes.len()))?;
    Ok(msg)
}

/// Serialises a JointState as ROS 2 does (CDR little endian with its
/// encapsulation header): for tests and benchmarks that write bags.
pub fn encode_joint_state(msg: &JointState) -> Result<Vec<u8>, String> {
    let body = cdr_encoding::to_vec::<JointState, byteorder::LittleEndian>(msg).map_err(|e| e.to_string())?;
    let mut out = Vec::with_capacity(body.len() + 4);
    out.extend_from_slice(&[0, 1, 0, 0]);
    out.extend_from_slice(&body);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The CDR bytes of a JointState written out by hand from the CDR rules
    /// (independent of the crate's serialiser).
    fn by_hand() -> Vec<u8> {
        let mut b = vec![0u8, 1, 0, 0];
        let mut body: Vec<u8> = Vec::new();
        let align = |body: &mut Vec<u8>, n: usize| {
            while body.len() % n != 0 {
                body.push(0);
            }
        };
        body.extend(7i32.to_le_bytes()); // sec
        body.extend(500u32.to_le_bytes()); // nanosec
        body.extend(5u32.to_le_bytes()); // frame_id "base" + NUL
        body.extend(b"base\0");
        align(&mut body, 4);
        body.extend(2u32.to_le_bytes()); // 2 names
        for n in ["j1", "joint_2"] {
            body.extend(((n.len() + 1) as u32).to_le_bytes());
            body.extend(n.as_bytes());
            body.push(0);
            align(&mut body, 4);
        }
        for v in [vec![0.5, -1.25], vec![], vec![3.0, 4.0]] {
            align(&mut body, 4);
            body.extend((v.len() as u32).to_le_bytes());
            if !v.is_empty() {
                align(&mut body, 8);
            }
            for x in v {
                body.extend(f64::to_le_bytes(x));
            }
        }
        b.extend(body);
        b
    }

    #[test]
    fn decodes_a_message_written_by_hand_and_round_trips() {
        let m = decode_joint_state(&by_hand()).unwrap();
        assert_eq!(m.header.stamp, Time { sec: 7, nanosec: 500 });
        assert_eq!(m.header.frame_id, "base");
        assert_eq!(m.name, ["j1", "joint_2"]);
        assert_eq!(m.position, [0.5, -1.25]);
        assert!(m.velocity.is_empty());
        assert_eq!(m.effort, [3.0, 4.0]);
        assert_eq!(m.header.stamp.nanoseconds().unwrap(), 7_000_000_500);
        assert_eq!(decode_joint_state(&encode_joint_state(&m).unwrap()).unwrap(), m);
        // every truncation is an error, never a panic
        let b = by_hand();
        for k in 0..b.len() - 1 {
            assert!(decode_joint_state(&b[..k]).is_err(), "truncated at {k}");
        }
        // a huge sequence length is refused at the end of the bytes
        let mut huge = b.clone();
        let at = 4 + 8 + 4 + 8; // the name count
        huge[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(decode_joint_state(&huge).is_err());
        assert!(decode_joint_state(&[0, 7, 0, 0, 1, 2, 3]).unwrap_err().contains("encapsulation"));
        assert!(Time {
            sec: 1,
            nanosec: 1_000_000_000
        }
        .nanoseconds()
        .is_err());
        // big endian (encapsulation 00 00) decodes to the same message
        let mut be = vec![0u8, 0, 0, 0];
        be.extend(cdr_encoding::to_vec::<JointState, byteorder::BigEndian>(&m).unwrap());
        assert_eq!(decode_joint_state(&be).unwrap(), m);
        assert_ne!(be[4..], encode_joint_state(&m).unwrap()[4..]);
    }
}
