//! CDR, as rosbag2 stores ROS 2 messages: a 4-byte encapsulation header, then the fields in
//! declaration order, each primitive aligned to its size (relative to the end of the header).
//!
//! Read: plain CDR (XCDR1, encapsulation `0x0000` big-endian / `0x0001` little-endian) and plain
//! XCDR2 (`0x0006` / `0x0007`, where 8-byte primitives align to 4 only). Written: XCDR1
//! little-endian, what rmw_fastrtps and rosbag2 write. Only the messages the replay needs have
//! readers and writers here (`sensor_msgs/JointState`, `std_msgs/String`,
//! `std_msgs/Float64MultiArray` (read only), `spatial_dynamics_msgs/JointDynamics`); they borrow from the message bytes and allocate
//! nothing, and the writers append to a caller's buffer.
//!
//! Layouts (`align` is relative to the first byte after the header):
//! - `string`: `uint32` length including the terminating NUL, the bytes, the NUL;
//! - `T[]`: `uint32` count, then the elements (each aligned);
//! - `builtin_interfaces/Time`: `int32 sec`, `uint32 nanosec`; `std_msgs/Header`: stamp, `string frame_id`;
//! - `std_msgs/Float64MultiArray`: `MultiArrayLayout layout` (`MultiArrayDimension[] dim`, each
//!   `string label`, `uint32 size`, `uint32 stride`; then `uint32 data_offset`), `float64[] data`.

use std::ops::Range;

/// A sequence of `float64` in the message bytes (possibly unaligned, either byte order).
#[derive(Clone, Copy, Debug)]
pub struct F64s<'a> {
    bytes: &'a [u8],
    little: bool,
}

impl<'a> F64s<'a> {
    /// The values, decoded.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = f64> + 'a {
        let little = self.little;
        self.bytes.chunks_exact(8).map(move |c| {
            let b: [u8; 8] = c.try_into().expect("chunks of 8");
            if little {
                f64::from_le_bytes(b)
            } else {
                f64::from_be_bytes(b)
            }
        })
    }

    /// Decodes the values into `out` (cleared first).
    pub fn read_into(&self, out: &mut Vec<f64>) {
        out.clear();
        out.extend(self.iter());
    }
}

/// A `sensor_msgs/JointState`, borrowed from its CDR bytes.
#[derive(Clone, Debug)]
pub struct JointStateView<'a> {
    data: &'a [u8],
    pub sec: i32,
    pub nanosec: u32,
    pub frame_id: &'a str,
    pub position: F64s<'a>,
    pub velocity: F64s<'a>,
    pub effort: F64s<'a>,
}

impl<'a> JointStateView<'a> {
    /// The bytes of name `i` (a range of [`parse_joint_state`]'s `names`); not checked as UTF-8.
    pub fn name_bytes(&self, range: &Range<usize>) -> &'a [u8] {
        &self.data[range.clone()]
    }
}

/// Reads the fields of one message, in order.
struct Reader<'a> {
    data: &'a [u8],
    /// Offset of the first byte after the encapsulation header.
    origin: usize,
    pos: usize,
    little: bool,
    /// Largest alignment of a primitive: 8 in XCDR1, 4 in XCDR2.
    max_align: usize,
}

impl<'a> Reader<'a> {
    fn new(data: &'a [u8]) -> Result<Reader<'a>, String> {
        if data.len() < 4 {
            return Err(format!(
                "{} bytes: too short for a CDR message (a 4-byte header first)",
                data.len()
            ));
        }
        let (little, max_align) = match (data[0], data[1]) {
            (0, 0) => (false, 8),
            (0, 1) => (true, 8),
            (0, 6) => (false, 4),
            (0, 7) => (true, 4),
            (a, b) => {
                return Err(format!(
                    "CDR encapsulation {a:#04x}{b:02x} is not plain CDR (0x0000, 0x0001) or plain XCDR2 (0x0006, 0x0007)"
                ))
            }
        };
        Ok(Reader {
            data,
            origin: 4,
            pos: 4,
            little,
            max_align,
        })
    }

    fn take(&mut self, n: usize, align: usize, field: &str) -> Result<&'a [u8], String> {
        // Alignments are powers of two: the padding is −rel mod align.
        let align = align.min(self.max_align);
        let rel = self.pos - self.origin;
        let start = self.pos + (rel.wrapping_neg() & (align - 1));
        let end = start.checked_add(n).filter(|&e| e <= self.data.len());
        let Some(end) = end else {
            return Err(format!(
                "{field}: the message ends at byte {} (needs {n} more bytes at {start})",
                self.data.len()
            ));
        };
        self.pos = end;
        Ok(&self.data[start..end])
    }

    fn u32(&mut self, field: &str) -> Result<u32, String> {
        let b: [u8; 4] = self.take(4, 4, field)?.try_into().expect("4 bytes");
        Ok(if self.little {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        })
    }

    /// A string's bytes without the NUL, as a byte range of the message.
    fn string_range(&mut self, field: &str) -> Result<Range<usize>, String> {
        let n = self.u32(field)? as usize;
        let bytes = self.take(n, 1, field)?;
        let start = self.pos - n;
        match bytes.last() {
            Some(0) => Ok(start..start + n - 1),
            // Some writers leave out the NUL of an empty string (length 0).
            None => Ok(start..start),
            Some(_) => Err(format!("{field}: string is not NUL-terminated")),
        }
    }

    fn string(&mut self, field: &str) -> Result<&'a str, String> {
        let r = self.string_range(field)?;
        std::str::from_utf8(&self.data[r]).map_err(|_| format!("{field}: string is not UTF-8"))
    }

    fn f64s(&mut self, field: &str) -> Result<F64s<'a>, String> {
        let n = self.u32(field)? as usize;
        if n == 0 {
            // No element, no alignment.
            return Ok(F64s {
                bytes: &[],
                little: self.little,
            });
        }
        let bytes = n
            .checked_mul(8)
            .ok_or_else(|| format!("{field}: {n} values overflow"))?;
        let bytes = self.take(bytes, 8, field)?;
        Ok(F64s {
            bytes,
            little: self.little,
        })
    }
}

/// Parses a `sensor_msgs/JointState`. The joint names go to `names` as byte ranges of `data`
/// (cleared first; read them with [`JointStateView::name_bytes`]), so that nothing is allocated.
pub fn parse_joint_state<'a>(
    data: &'a [u8],
    names: &mut Vec<Range<usize>>,
) -> Result<JointStateView<'a>, String> {
    let mut r = Reader::new(data)?;
    let sec = r.u32("header.stamp.sec")? as i32;
    let nanosec = r.u32("header.stamp.nanosec")?;
    let frame_id = r.string("header.frame_id")?;
    let count = r.u32("name")? as usize;
    names.clear();
    for _ in 0..count {
        // Each name is at least 4 bytes (its length): a huge count fails here, not in `reserve`.
        names.push(r.string_range("name")?);
    }
    let position = r.f64s("position")?;
    let velocity = r.f64s("velocity")?;
    let effort = r.f64s("effort")?;
    Ok(JointStateView {
        data,
        sec,
        nanosec,
        frame_id,
        position,
        velocity,
        effort,
    })
}

/// Parses a `std_msgs/Float64MultiArray` into its `data` (the layout is read and checked for
/// length, not interpreted: `~/commands` is one value per commanded joint). A dimension count
/// is checked against the bytes that remain before any is read; errors name the field and the
/// byte offset.
pub fn parse_float64_multi_array(data: &[u8]) -> Result<F64s<'_>, String> {
    let mut r = Reader::new(data)?;
    let count = r.u32("layout.dim")? as usize;
    // Each dimension takes at least 12 bytes: an empty label's length, size, stride.
    let remaining = data.len() - r.pos;
    if count > remaining / 12 {
        return Err(format!(
            "layout.dim: {count} dimensions need at least {} bytes, {remaining} remain after byte {}",
            count as u64 * 12,
            r.pos
        ));
    }
    for _ in 0..count {
        r.string_range("layout.dim.label")?;
        r.u32("layout.dim.size")?;
        r.u32("layout.dim.stride")?;
    }
    r.u32("layout.data_offset")?;
    r.f64s("data")
}

/// Parses a `std_msgs/String`.
pub fn parse_string(data: &[u8]) -> Result<&str, String> {
    Reader::new(data)?.string("data")
}

/// Appends one XCDR1 little-endian message to a buffer.
pub struct Writer<'b> {
    buf: &'b mut Vec<u8>,
    /// Offset of the first byte after the encapsulation header.
    origin: usize,
}

impl<'b> Writer<'b> {
    /// Starts a message at the end of `buf` with its encapsulation header (CDR little-endian).
    pub fn new(buf: &'b mut Vec<u8>) -> Writer<'b> {
        buf.extend_from_slice(&[0, 1, 0, 0]);
        let origin = buf.len();
        Writer { buf, origin }
    }

    fn align(&mut self, n: usize) {
        let rel = self.buf.len() - self.origin;
        let pad = rel.wrapping_neg() & (n - 1); // n is a power of two
        self.buf.extend_from_slice(&[0u8; 8][..pad]);
    }

    /// `uint32`.
    pub fn u32(&mut self, x: u32) {
        self.align(4);
        self.buf.extend_from_slice(&x.to_le_bytes());
    }

    /// `string`.
    pub fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }

    /// `builtin_interfaces/Time stamp` then `string frame_id`: a `std_msgs/Header`.
    pub fn header(&mut self, sec: i32, nanosec: u32, frame_id: &str) {
        self.u32(sec as u32);
        self.u32(nanosec);
        self.string(frame_id);
    }

    /// A field encoded beforehand by [`encode_strings`]: copied as is (it needs alignment 4 only).
    pub fn encoded_strings(&mut self, encoded: &[u8]) {
        self.align(4);
        self.buf.extend_from_slice(encoded);
    }

    /// `float64[]`.
    pub fn f64s(&mut self, values: impl ExactSizeIterator<Item = f64>) {
        self.u32(values.len() as u32);
        if values.len() > 0 {
            self.align(8);
            // Sized once, then filled in place (no capacity check per value).
            let start = self.buf.len();
            self.buf.resize(start + 8 * values.len(), 0);
            for (out, x) in self.buf[start..].chunks_exact_mut(8).zip(values) {
                out.copy_from_slice(&x.to_le_bytes());
            }
        }
    }
}

/// A `string[]` field encoded once, to be copied into many messages by
/// [`Writer::encoded_strings`]: inside it only 4-byte alignment occurs, so its bytes are the same
/// at any 4-aligned offset.
pub fn encode_strings<S: AsRef<str>>(strings: &[S]) -> Vec<u8> {
    let mut buf = Vec::new();
    let mut w = Writer::new(&mut buf);
    w.u32(strings.len() as u32);
    for s in strings {
        w.string(s.as_ref());
    }
    buf.split_off(4)
}

/// `std_msgs/String` (bags for tests).
#[cfg(test)]
pub fn write_string_msg(buf: &mut Vec<u8>, data: &str) {
    Writer::new(buf).string(data);
}

#[cfg(test)]
mod tests {
    //! Round trips against `cdr-encoding`, the serializer ros2-client puts on the wire, with
    //! the node's message structs: what we write it reads back, and what it writes we read.
    use super::*;
    use crate::ros::msgs::{
        Float64MultiArray, Header, JointDynamics, JointState, MultiArrayDimension,
        MultiArrayLayout, StringMsg, Time,
    };
    use byteorder::{BigEndian, LittleEndian};

    fn state(frame_id: &str, names: &[&str], n: [usize; 3]) -> JointState {
        let values = |k: usize, scale: f64| (0..k).map(|i| scale * (i as f64 + 0.25)).collect();
        JointState {
            header: Header {
                stamp: Time {
                    sec: -3,
                    nanosec: 999_999_999,
                },
                frame_id: frame_id.into(),
            },
            name: names.iter().map(|s| s.to_string()).collect(),
            position: values(n[0], 1.5),
            velocity: values(n[1], -2.0),
            effort: values(n[2], 1e-300),
        }
    }

    fn with_header(encapsulation: [u8; 4], body: Vec<u8>) -> Vec<u8> {
        encapsulation.iter().copied().chain(body).collect()
    }

    fn read_back(bytes: &[u8]) -> JointState {
        let mut ranges = Vec::new();
        let v = parse_joint_state(bytes, &mut ranges).unwrap();
        JointState {
            header: Header {
                stamp: Time {
                    sec: v.sec,
                    nanosec: v.nanosec,
                },
                frame_id: v.frame_id.into(),
            },
            name: ranges
                .iter()
                .map(|r| String::from_utf8(v.name_bytes(r).to_vec()).unwrap())
                .collect(),
            position: v.position.iter().collect(),
            velocity: v.velocity.iter().collect(),
            effort: v.effort.iter().collect(),
        }
    }

    /// Frame ids and names of every length mod 8 move the float arrays across alignments.
    fn cases() -> Vec<JointState> {
        let mut out = Vec::new();
        for frame in ["", "a", "ab", "abc", "base_link", "wörld"] {
            for names in [&[][..], &["j1"][..], &["shoulder", "e", "wrist_3"][..]] {
                for n in [[0, 0, 0], [names.len(); 3], [2, 0, 1], [7, 7, 0]] {
                    out.push(state(frame, names, n));
                }
            }
        }
        out
    }

    #[test]
    fn joint_state_written_by_cdr_encoding_is_read_in_both_byte_orders() {
        for msg in cases() {
            let le = cdr_encoding::to_vec::<_, LittleEndian>(&msg).unwrap();
            assert_eq!(read_back(&with_header([0, 1, 0, 0], le)), msg);
            let be = cdr_encoding::to_vec::<_, BigEndian>(&msg).unwrap();
            assert_eq!(read_back(&with_header([0, 0, 0, 0], be)), msg);
        }
    }

    #[test]
    fn joint_state_and_joint_dynamics_we_write_are_read_by_cdr_encoding() {
        for msg in cases() {
            let mut buf = vec![0xAA; 3]; // a message need not start at an aligned buffer offset
            let mut w = Writer::new(&mut buf);
            w.header(
                msg.header.stamp.sec,
                msg.header.stamp.nanosec,
                &msg.header.frame_id,
            );
            w.encoded_strings(&encode_strings(&msg.name));
            w.f64s(msg.position.iter().copied());
            w.f64s(msg.velocity.iter().copied());
            w.f64s(msg.effort.iter().copied());
            assert_eq!(&buf[3..7], &[0, 1, 0, 0]);
            let (back, used) =
                cdr_encoding::from_bytes::<JointState, LittleEndian>(&buf[7..]).unwrap();
            assert_eq!(back, msg);
            assert_eq!(used, buf.len() - 7, "no trailing bytes");
            assert_eq!(read_back(&buf[3..]), msg);

            let dynamics = JointDynamics {
                header: msg.header.clone(),
                name: msg.name.clone(),
                position: msg.position.clone(),
                velocity: msg.velocity.clone(),
                acceleration: msg.effort.iter().map(|x| x * 3.0).collect(),
                effort: msg.velocity.clone(),
            };
            let mut buf = Vec::new();
            let mut w = Writer::new(&mut buf);
            w.header(
                msg.header.stamp.sec,
                msg.header.stamp.nanosec,
                &msg.header.frame_id,
            );
            w.encoded_strings(&encode_strings(&dynamics.name));
            for field in [
                &dynamics.position,
                &dynamics.velocity,
                &dynamics.acceleration,
                &dynamics.effort,
            ] {
                w.f64s(field.iter().copied());
            }
            let (back, _) =
                cdr_encoding::from_bytes::<JointDynamics, LittleEndian>(&buf[4..]).unwrap();
            assert_eq!(back, dynamics);
        }
    }

    #[test]
    fn float64_multi_array_written_by_cdr_encoding_is_read_in_both_byte_orders() {
        for dims in [0usize, 1, 3] {
            for n in [0usize, 1, 6, 7] {
                let msg = Float64MultiArray {
                    layout: MultiArrayLayout {
                        dim: (0..dims)
                            .map(|k| MultiArrayDimension {
                                label: "ab".repeat(k),
                                size: n as u32,
                                stride: (n * (k + 1)) as u32,
                            })
                            .collect(),
                        data_offset: dims as u32,
                    },
                    data: (0..n).map(|k| k as f64 - 2.5).collect(),
                };
                let le = cdr_encoding::to_vec::<_, LittleEndian>(&msg).unwrap();
                let bytes = with_header([0, 1, 0, 0], le);
                let back: Vec<f64> = parse_float64_multi_array(&bytes).unwrap().iter().collect();
                assert_eq!(back, msg.data);
                let be = cdr_encoding::to_vec::<_, BigEndian>(&msg).unwrap();
                let bytes_be = with_header([0, 0, 0, 0], be);
                let back: Vec<f64> = parse_float64_multi_array(&bytes_be)
                    .unwrap()
                    .iter()
                    .collect();
                assert_eq!(back, msg.data);
                for cut in 0..bytes.len() {
                    assert!(
                        parse_float64_multi_array(&bytes[..cut]).is_err(),
                        "cut at {cut}"
                    );
                }
            }
        }
    }

    #[test]
    fn float64_multi_array_lengths_are_checked_against_the_bytes() {
        let msg = Float64MultiArray {
            layout: MultiArrayLayout {
                dim: vec![MultiArrayDimension {
                    label: "joints".into(),
                    size: 2,
                    stride: 2,
                }],
                data_offset: 0,
            },
            data: vec![1.0, 2.0],
        };
        let full = with_header(
            [0, 1, 0, 0],
            cdr_encoding::to_vec::<_, LittleEndian>(&msg).unwrap(),
        );
        // A dimension count of 2^32 − 1: refused before reading one, naming the offset.
        let mut huge = full.clone();
        huge[4..8].copy_from_slice(&u32::MAX.to_le_bytes());
        let err = parse_float64_multi_array(&huge).unwrap_err();
        assert!(
            err.starts_with("layout.dim:") && err.contains("after byte 8"),
            "{err}"
        );
        // A data count of 2^29 (4 GiB of doubles): refused on the bytes, naming where.
        let at = full.len() - 16 - 4;
        let mut long = full.clone();
        long[at..at + 4].copy_from_slice(&(1u32 << 29).to_le_bytes());
        let err = parse_float64_multi_array(&long).unwrap_err();
        assert!(
            err.starts_with("data:") && err.contains(&format!("ends at byte {}", full.len())),
            "{err}"
        );
    }

    #[test]
    fn strings_round_trip() {
        for s in ["", "x", "<robot name=\"r\"/>"] {
            let mut buf = Vec::new();
            write_string_msg(&mut buf, s);
            let (back, _) = cdr_encoding::from_bytes::<StringMsg, LittleEndian>(&buf[4..]).unwrap();
            assert_eq!(back.data, s);
            assert_eq!(parse_string(&buf).unwrap(), s);
        }
    }

    #[test]
    fn xcdr2_aligns_doubles_to_four() {
        // Offsets after the header: stamp 0..8, frame_id "a" 8..14 (+2 padding), name[] count
        // 16..20, position count 20..24 and its double at 24 (aligned either way), velocity
        // count 32..36 and its double at 36: XCDR2 aligns it to 4, XCDR1 would look at 40.
        let mut body = Vec::new();
        body.extend_from_slice(&7i32.to_le_bytes());
        body.extend_from_slice(&8u32.to_le_bytes());
        body.extend_from_slice(&2u32.to_le_bytes());
        body.extend_from_slice(b"a\0\0\0");
        body.extend_from_slice(&0u32.to_le_bytes());
        body.extend_from_slice(&1u32.to_le_bytes());
        body.extend_from_slice(&2.5f64.to_le_bytes());
        body.extend_from_slice(&1u32.to_le_bytes());
        body.extend_from_slice(&(-1.0f64).to_le_bytes());
        body.extend_from_slice(&0u32.to_le_bytes()); // effort[]
        let back = read_back(&with_header([0, 7, 0, 0], body.clone()));
        assert_eq!(back.position, [2.5]);
        assert_eq!(back.velocity, [-1.0]);
        assert!(back.effort.is_empty());
        let mut ranges = Vec::new();
        assert!(parse_joint_state(&with_header([0, 1, 0, 0], body), &mut ranges).is_err());
    }

    #[test]
    fn truncated_and_malformed_messages_are_errors_naming_the_field() {
        let msg = state("base", &["j1", "j2"], [2, 2, 2]);
        let full = with_header(
            [0, 1, 0, 0],
            cdr_encoding::to_vec::<_, LittleEndian>(&msg).unwrap(),
        );
        let mut ranges = Vec::new();
        for cut in 0..full.len() {
            assert!(
                parse_joint_state(&full[..cut], &mut ranges).is_err(),
                "cut at {cut}"
            );
        }
        let err = parse_joint_state(&full[..full.len() - 3], &mut ranges).unwrap_err();
        assert!(err.starts_with("effort:"), "{err}");
        let mut bad = full.clone();
        bad[1] = 3;
        assert!(parse_joint_state(&bad, &mut ranges)
            .unwrap_err()
            .contains("encapsulation"));
        // A name count of 2^32 - 1 fails on the bytes, without trying to allocate.
        let mut huge = full.clone();
        let at = 4 + 8 + 4 + 5 + 3; // after stamp and "base\0" padded
        huge[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(parse_joint_state(&huge, &mut ranges)
            .unwrap_err()
            .starts_with("name:"));
    }
}
