//! NumPy's `.npy` format, version 1.0, for the float32 arrays a run holds (the simulator's
//! traction maps, height maps): little-endian, C order (numpy.org/neps/nep-0001-npy-format).
//! Written here so that `numpy.load` reads them with no gelrig, and read back by the export.

/// The file's bytes: a float32 array of `shape` (C order) holding `data`.
pub fn encode(data: &[f32], shape: &[usize]) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let tuple = match dims.len() {
        1 => format!("({},)", dims[0]),
        _ => format!("({})", dims.join(", ")),
    };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {tuple}, }}");
    // Magic (6) + version (2) + length (2) + header + '\n' to a multiple of 64.
    let total = (10 + header.len() + 1).div_ceil(64) * 64;
    header.push_str(&" ".repeat(total - 10 - header.len() - 1));
    header.push('\n');
    let mut bytes = Vec::with_capacity(total + 4 * data.len());
    bytes.extend_from_slice(b"\x93NUMPY\x01\x00");
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    for v in data {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    bytes
}

/// A float32 C-order array read back: its shape and values. Any other file (another type,
/// Fortran order, a torn tail) is an error saying what was found.
pub fn decode(bytes: &[u8]) -> Result<(Vec<usize>, Vec<f32>), String> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err("not a NumPy .npy file (no \\x93NUMPY magic)".into());
    }
    let (len, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
        v => return Err(format!(".npy version {v} is not read here")),
    };
    let header = bytes
        .get(start..start + len)
        .and_then(|h| std::str::from_utf8(h).ok())
        .ok_or("the .npy header is cut short or not text")?;
    if !header.contains("'descr': '<f4'") || !header.contains("'fortran_order': False") {
        return Err(format!(
            "the array is not little-endian float32 in C order: {}",
            header.trim()
        ));
    }
    let shape_text = header
        .split("'shape':")
        .nth(1)
        .and_then(|t| t.split(')').next())
        .map(|t| t.trim().trim_start_matches('('))
        .ok_or("the .npy header has no shape")?;
    let shape = shape_text
        .split(',')
        .map(str::trim)
        .filter(|t| !t.is_empty())
        .map(|t| {
            t.parse::<usize>()
                .map_err(|_| format!("shape `{shape_text}`"))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let count: usize = shape.iter().product();
    let body = &bytes[start + len..];
    if body.len() != 4 * count {
        return Err(format!(
            "shape {shape:?} needs {} bytes of data, the file has {}",
            4 * count,
            body.len()
        ));
    }
    let values = body
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Ok((shape, values))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arrays_come_back_as_written_and_bad_files_are_named() {
        let data: Vec<f32> = (0..24).map(|i| i as f32 * 0.5 - 3.0).collect();
        for shape in [vec![24], vec![4, 6], vec![2, 3, 4]] {
            let bytes = encode(&data, &shape);
            assert_eq!((10 + bytes[8] as usize + 256 * bytes[9] as usize) % 64, 0);
            assert_eq!(decode(&bytes), Ok((shape, data.clone())));
        }
        let bytes = encode(&data, &[4, 6]);
        let torn = decode(&bytes[..bytes.len() - 3]).expect_err("a torn file");
        assert!(torn.contains("needs 96 bytes"), "{torn}");
        assert!(decode(b"PK\x03\x04 a zip file").is_err());
        let mut f8 = bytes.clone();
        let at = f8.windows(3).position(|w| w == b"<f4").expect("descr");
        f8[at + 2] = b'8';
        assert!(decode(&f8).expect_err("float64").contains("float32"));
    }
}
