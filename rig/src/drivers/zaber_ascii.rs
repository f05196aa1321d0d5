//! Zaber ASCII framing, shared by the driver and its twin so both read the same grammar
//! (Zaber ASCII protocol manual; spec `devices.md` §2a).
//!
//! Command: `/DD A ID cmd args[:CC]\n`; reply: `@DD A ID OK|RJ IDLE|BUSY WW data[:CC]\r\n`;
//! `#` info and `!` alert lines may interleave. CC is the LRC: the two's complement of the
//! byte sum (mod 256) of the text between the leading `/` or `@` and the `:`.

/// LRC of `body` (the text after `/` or `@`, before `:`). Test vector: `01 tools echo` →
/// 0x8F (zproto `src/ascii/checksum.rs`).
pub fn lrc(body: &str) -> u8 {
    body.bytes()
        .fold(0u8, |a, b| a.wrapping_add(b))
        .wrapping_neg()
}

/// Appends `:CC` when `checksum` is set.
pub fn with_checksum(body: &str, checksum: bool) -> String {
    if checksum {
        format!("{body}:{:02X}", lrc(body))
    } else {
        body.to_string()
    }
}

/// Splits a line after its lead character into body and checksum, verifying it if present.
/// `Err` names what is wrong.
pub fn verify(after_lead: &str) -> Result<&str, String> {
    match after_lead.rsplit_once(':') {
        Some((body, cc)) => {
            let want = u8::from_str_radix(cc.trim(), 16)
                .map_err(|_| format!("checksum `{cc}` is not hex"))?;
            let got = lrc(body);
            if got == want {
                Ok(body)
            } else {
                Err(format!("checksum {want:02X} does not match {got:02X}"))
            }
        }
        None => Ok(after_lead),
    }
}

/// A parsed reply.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reply {
    /// Device address.
    pub device: u8,
    /// Axis number (0 = device).
    pub axis: u8,
    /// Message id, if the command carried one.
    pub id: Option<u8>,
    /// `OK` (true) or `RJ` (false).
    pub ok: bool,
    /// `BUSY` (true) or `IDLE`.
    pub busy: bool,
    /// Highest-priority warning flag, `None` for `--`.
    pub warning: Option<String>,
    /// Data field (a value, or the rejection reason).
    pub data: String,
}

/// Parses a reply line (`@…`), checksum included. `Err` says what is wrong.
pub fn parse_reply(line: &str) -> Result<Reply, String> {
    let line = line.trim_end_matches(['\r', '\n']);
    let rest = line
        .strip_prefix('@')
        .ok_or_else(|| format!("`{}` is not a reply (no `@`)", crate::quote(line)))?;
    let body = verify(rest)?;
    let f: Vec<&str> = body.split_whitespace().collect();
    // With an id there are 7 fields, without 6 (data may contain spaces: join the tail).
    let with_id = f.len() >= 7 && f[2].parse::<u8>().is_ok() && matches!(f[3], "OK" | "RJ");
    let (id, k) = if with_id {
        (f[2].parse().ok(), 3)
    } else {
        (None, 2)
    };
    if f.len() < k + 4 {
        return Err(format!("`{}` has too few fields", crate::quote(line)));
    }
    let num = |s: &str, what: &str| {
        s.parse::<u8>().map_err(|_| {
            format!(
                "{what} `{}` in `{}` is not a number",
                crate::quote(s),
                crate::quote(line)
            )
        })
    };
    let ok = match f[k] {
        "OK" => true,
        "RJ" => false,
        other => {
            return Err(format!(
                "reply flag `{}` is neither OK nor RJ",
                crate::quote(other)
            ));
        }
    };
    let busy = match f[k + 1] {
        "BUSY" => true,
        "IDLE" => false,
        other => {
            return Err(format!(
                "status `{}` is neither BUSY nor IDLE",
                crate::quote(other)
            ));
        }
    };
    Ok(Reply {
        device: num(f[0], "device")?,
        axis: num(f[1], "axis")?,
        id,
        ok,
        busy,
        warning: (f[k + 2] != "--").then(|| f[k + 2].to_string()),
        data: f[k + 3..].join(" "),
    })
}

/// A parsed command (`/…`), for the twin.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Command {
    /// Device address (0 = all).
    pub device: u8,
    /// Axis (0 = device).
    pub axis: u8,
    /// Message id.
    pub id: Option<u8>,
    /// The command words.
    pub words: Vec<String>,
}

/// Parses a command line; `Err` is the rejection reason a device would give.
pub fn parse_command(line: &str) -> Result<Command, &'static str> {
    let rest = line.trim().strip_prefix('/').ok_or("BADCOMMAND")?;
    let body = verify(rest).map_err(|_| "BADDATA")?;
    let mut f = body.split_whitespace().peekable();
    let num = |s: Option<&str>| s.and_then(|v| v.parse::<u8>().ok());
    let device = match f.peek() {
        Some(s) if s.parse::<u8>().is_ok() => num(f.next()).unwrap_or(0),
        _ => 0,
    };
    let axis = match f.peek() {
        Some(s) if s.parse::<u8>().is_ok() => num(f.next()).unwrap_or(0),
        _ => 0,
    };
    let id = match f.peek() {
        Some(s) if s.parse::<u8>().is_ok() => num(f.next()),
        _ => None,
    };
    Ok(Command {
        device,
        axis,
        id,
        words: f.map(str::to_string).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lrc_test_vector_and_round_trip() {
        assert_eq!(lrc("01 tools echo"), 0x8F);
        let line = format!("@{}\r\n", with_checksum("01 1 7 OK IDLE -- 1000", true));
        let r = parse_reply(&line).expect("parses");
        assert_eq!(
            (r.device, r.axis, r.id, r.ok, r.busy),
            (1, 1, Some(7), true, false)
        );
        assert_eq!(r.data, "1000");
        assert!(parse_reply("@01 1 7 OK IDLE -- 1000:00").is_err());
        let r = parse_reply("@01 0 RJ IDLE WR BADDATA").expect("parses");
        assert!(
            !r.ok && r.id.is_none() && r.warning.as_deref() == Some("WR") && r.data == "BADDATA"
        );
        assert!(parse_reply("garbage").is_err());
        assert!(parse_reply("@01 1 OK MAYBE -- 0").is_err());
        let c = parse_command("/1 1 12 move abs 1000:XX");
        assert_eq!(c, Err("BADDATA"));
        let c = parse_command(&format!("/{}", with_checksum("1 1 12 move abs 1000", true)))
            .expect("command");
        assert_eq!((c.device, c.axis, c.id), (1, 1, Some(12)));
        assert_eq!(c.words, ["move", "abs", "1000"]);
    }
}
