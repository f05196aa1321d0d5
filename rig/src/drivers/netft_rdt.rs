//! ATI Net F/T wire formats (spec `devices.md` §1a), shared by the driver and its twin.
//!
//! RDT over UDP: request `u16 0x1234 | u16 command | u32 sample_count`, big-endian;
//! records of 36 bytes `u32 rdt_sequence | u32 ft_sequence | u32 status | i32 Fx Fy Fz Tx Ty
//! Tz` (counts), one or more per datagram. Calibration over TCP (READCALINFO, manual
//! 9620-05 §11): request `0x01` + 19 zero bytes; reply `u16 0x1234, u8 force unit, u8
//! torque unit, u32 counts per force, u32 counts per torque, u16 scale[6]`.

/// Stop streaming.
pub const CMD_STOP: u16 = 0x0000;
/// Start real-time streaming (one record per datagram).
pub const CMD_START: u16 = 0x0002;
/// Start buffered streaming.
pub const CMD_START_BUFFERED: u16 = 0x0003;
/// Reset the threshold latch.
pub const CMD_RESET_LATCH: u16 = 0x0041;
/// Software bias (zero the current load).
pub const CMD_BIAS: u16 = 0x0042;
/// Size of one record.
pub const RECORD_LEN: usize = 36;
/// Status bit 31: any error.
pub const STATUS_ERROR: u32 = 1 << 31;
/// Status bit 30: a channel out of range.
pub const STATUS_OUT_OF_RANGE: u32 = 1 << 30;

/// An RDT request.
pub fn request(command: u16, count: u32) -> [u8; 8] {
    let mut b = [0u8; 8];
    b[0..2].copy_from_slice(&0x1234u16.to_be_bytes());
    b[2..4].copy_from_slice(&command.to_be_bytes());
    b[4..8].copy_from_slice(&count.to_be_bytes());
    b
}

/// Parses an RDT request; `None` if it is not one.
pub fn parse_request(b: &[u8]) -> Option<(u16, u32)> {
    if b.len() != 8 || b[0..2] != 0x1234u16.to_be_bytes() {
        return None;
    }
    Some((
        u16::from_be_bytes([b[2], b[3]]),
        u32::from_be_bytes([b[4], b[5], b[6], b[7]]),
    ))
}

/// One record.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Record {
    /// Packet counter.
    pub rdt_seq: u32,
    /// The box's internal sample counter.
    pub ft_seq: u32,
    /// Status bits.
    pub status: u32,
    /// Fx Fy Fz Tx Ty Tz in counts.
    pub counts: [i32; 6],
}

impl Record {
    /// Big-endian bytes.
    pub fn to_bytes(&self) -> [u8; RECORD_LEN] {
        let mut b = [0u8; RECORD_LEN];
        b[0..4].copy_from_slice(&self.rdt_seq.to_be_bytes());
        b[4..8].copy_from_slice(&self.ft_seq.to_be_bytes());
        b[8..12].copy_from_slice(&self.status.to_be_bytes());
        for (k, c) in self.counts.iter().enumerate() {
            b[12 + 4 * k..16 + 4 * k].copy_from_slice(&c.to_be_bytes());
        }
        b
    }

    /// Parses every record of a datagram; `None` unless its length is a positive multiple
    /// of 36.
    pub fn parse_all(b: &[u8]) -> Option<Vec<Record>> {
        if b.is_empty() || !b.len().is_multiple_of(RECORD_LEN) {
            return None;
        }
        let u = |o: usize| u32::from_be_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]);
        Some(
            (0..b.len() / RECORD_LEN)
                .map(|r| {
                    let o = r * RECORD_LEN;
                    Record {
                        rdt_seq: u(o),
                        ft_seq: u(o + 4),
                        status: u(o + 8),
                        counts: std::array::from_fn(|k| u(o + 12 + 4 * k) as i32),
                    }
                })
                .collect(),
        )
    }
}

/// Calibration information.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CalInfo {
    /// Force unit code (2 = N).
    pub force_unit: u8,
    /// Torque unit code (3 = N·m, 4 = N·mm).
    pub torque_unit: u8,
    /// Counts per force unit.
    pub counts_per_force: u32,
    /// Counts per torque unit.
    pub counts_per_torque: u32,
}

/// READCALINFO request.
pub const READCALINFO: [u8; 20] = {
    let mut b = [0u8; 20];
    b[0] = 0x01;
    b
};

impl CalInfo {
    /// Reply bytes (scale factors zero: unused).
    pub fn to_bytes(&self) -> [u8; 24] {
        let mut b = [0u8; 24];
        b[0..2].copy_from_slice(&0x1234u16.to_be_bytes());
        b[2] = self.force_unit;
        b[3] = self.torque_unit;
        b[4..8].copy_from_slice(&self.counts_per_force.to_be_bytes());
        b[8..12].copy_from_slice(&self.counts_per_torque.to_be_bytes());
        b
    }

    /// Parses a reply; `Err` says what is wrong.
    pub fn parse(b: &[u8]) -> Result<Self, String> {
        if b.len() < 12 || b[0..2] != 0x1234u16.to_be_bytes() {
            return Err(format!(
                "calibration reply of {} bytes without the 0x1234 header",
                b.len()
            ));
        }
        let c = CalInfo {
            force_unit: b[2],
            torque_unit: b[3],
            counts_per_force: u32::from_be_bytes([b[4], b[5], b[6], b[7]]),
            counts_per_torque: u32::from_be_bytes([b[8], b[9], b[10], b[11]]),
        };
        if c.counts_per_force == 0 || c.counts_per_torque == 0 {
            return Err("zero counts per unit".into());
        }
        Ok(c)
    }

    /// The force and torque units by name (codes as in [`Self::scales`]).
    pub fn unit_names(&self) -> (String, String) {
        let f = match self.force_unit {
            1 => "lbf",
            2 => "N",
            3 => "klbf",
            4 => "kN",
            5 => "kgf",
            6 => "gf",
            u => {
                return (
                    format!("force unit {u}"),
                    format!("torque unit {}", self.torque_unit),
                );
            }
        };
        let t = match self.torque_unit {
            1 => "lbf·in",
            2 => "lbf·ft",
            3 => "N·m",
            4 => "N·mm",
            5 => "kgf·cm",
            6 => "kN·m",
            u => return (f.to_string(), format!("torque unit {u}")),
        };
        (f.to_string(), t.to_string())
    }

    /// N per count and N·mm per count, from the unit codes (force: 1 lbf, 2 N, 3 klbf,
    /// 4 kN, 5 kgf, 6 gf; torque: 1 lbf-in, 2 lbf-ft, 3 N-m, 4 N-mm, 5 kgf-cm, 6 kN-m).
    pub fn scales(&self) -> Result<(f64, f64), String> {
        let f = match self.force_unit {
            1 => 4.448_221_615,
            2 => 1.0,
            3 => 4_448.221_615,
            4 => 1000.0,
            5 => 9.806_65,
            6 => 0.009_806_65,
            u => return Err(format!("unknown force unit code {u}")),
        };
        let t = match self.torque_unit {
            1 => 112.984_829,
            2 => 1_355.817_948,
            3 => 1000.0,
            4 => 1.0,
            5 => 98.0665,
            6 => 1.0e6,
            u => return Err(format!("unknown torque unit code {u}")),
        };
        Ok((
            f / self.counts_per_force as f64,
            t / self.counts_per_torque as f64,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_and_requests_round_trip() {
        let r = Record {
            rdt_seq: 7,
            ft_seq: u32::MAX,
            status: STATUS_OUT_OF_RANGE,
            counts: [1, -2, 3, -4, 5, i32::MIN],
        };
        let mut two = r.to_bytes().to_vec();
        two.extend(r.to_bytes());
        assert_eq!(Record::parse_all(&two), Some(vec![r, r]));
        assert_eq!(Record::parse_all(&two[..35]), None);
        assert_eq!(parse_request(&request(CMD_BIAS, 0)), Some((CMD_BIAS, 0)));
        assert_eq!(parse_request(&[0; 8]), None);
        let c = CalInfo {
            force_unit: 2,
            torque_unit: 3,
            counts_per_force: 1_500_000,
            counts_per_torque: 2_000,
        };
        assert_eq!(CalInfo::parse(&c.to_bytes()), Ok(c));
        let (f, t) = c.scales().expect("units");
        assert!((f - 1.0 / 1.5e6).abs() < 1e-18 && (t - 1000.0 / 2000.0).abs() < 1e-12);
    }
}
