//! Little-endian CDR (XCDR1, OMG DDS-XTypes §7.4.1), as ROS 2 serialises its messages: a
//! 4-byte encapsulation header `00 01 00 00`, then each field in order at its natural
//! alignment counted from the end of that header; strings as a u32 length that includes the
//! NUL, the bytes, the NUL; sequences as a u32 count, then the elements.

/// A CDR payload being written.
pub(super) struct Cdr {
    buf: Vec<u8>,
}

impl Cdr {
    /// A payload with its encapsulation header.
    pub(super) fn new() -> Self {
        Self {
            buf: vec![0x00, 0x01, 0x00, 0x00],
        }
    }

    fn align(&mut self, n: usize) {
        let at = self.buf.len() - 4;
        let pad = (n - at % n) % n;
        self.buf.extend(std::iter::repeat_n(0u8, pad));
    }

    pub(super) fn u32(&mut self, v: u32) -> &mut Self {
        self.align(4);
        self.buf.extend(v.to_le_bytes());
        self
    }

    pub(super) fn i32(&mut self, v: i32) -> &mut Self {
        self.align(4);
        self.buf.extend(v.to_le_bytes());
        self
    }

    pub(super) fn u8(&mut self, v: u8) -> &mut Self {
        self.buf.push(v);
        self
    }

    pub(super) fn f32(&mut self, v: f32) -> &mut Self {
        self.align(4);
        self.buf.extend(v.to_le_bytes());
        self
    }

    /// Four `float32` fields in a row (a `std_msgs/ColorRGBA`).
    pub(super) fn f32x4(&mut self, v: [f32; 4]) -> &mut Self {
        for x in v {
            self.f32(x);
        }
        self
    }

    pub(super) fn f64(&mut self, v: f64) -> &mut Self {
        self.align(8);
        self.buf.extend(v.to_le_bytes());
        self
    }

    pub(super) fn string(&mut self, s: &str) -> &mut Self {
        self.u32(s.len() as u32 + 1);
        self.buf.extend(s.as_bytes());
        self.buf.push(0);
        self
    }

    pub(super) fn bytes(&mut self, b: &[u8]) -> &mut Self {
        self.u32(b.len() as u32);
        self.buf.extend(b);
        self
    }

    pub(super) fn strings(&mut self, v: &[String]) -> &mut Self {
        self.u32(v.len() as u32);
        for s in v {
            self.string(s);
        }
        self
    }

    pub(super) fn f64s(&mut self, v: &[f64]) -> &mut Self {
        self.u32(v.len() as u32);
        for x in v {
            self.f64(*x);
        }
        self
    }

    /// `std_msgs/Header`: the stamp on the run's clock and the frame id.
    pub(super) fn header(&mut self, t_ns: u64, frame_id: &str) -> &mut Self {
        self.i32((t_ns / 1_000_000_000).min(i32::MAX as u64) as i32)
            .u32((t_ns % 1_000_000_000) as u32)
            .string(frame_id)
    }

    pub(super) fn finish(self) -> Vec<u8> {
        self.buf
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_sit_at_their_natural_alignment_after_the_header() {
        let mut c = Cdr::new();
        c.string("a").f64(1.5).string("ab").u32(3);
        let b = c.finish();
        assert_eq!(&b[..4], &[0, 1, 0, 0]);
        // "a": length 2 (with the NUL), then "a\0": payload offsets 0..6.
        assert_eq!(&b[4..8], &2u32.to_le_bytes());
        assert_eq!(&b[8..10], b"a\0");
        // f64 realigned from payload offset 6 to 8 (buffer 12..20).
        assert_eq!(&b[12..20], &1.5f64.to_le_bytes());
        // string at payload 16: length 3, "ab\0" at 20..23.
        assert_eq!(&b[20..24], &3u32.to_le_bytes());
        assert_eq!(&b[24..27], b"ab\0");
        // u32 realigned from payload offset 23 to 24 (buffer 28..32).
        assert_eq!(&b[28..32], &3u32.to_le_bytes());
    }
}
