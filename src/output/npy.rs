//! NumPy `.npy` arrays: the AOVs' float and integer outputs, and reading them back to merge
//! tiles.
//!
//! The format (numpy.lib.format, version 1.0) is a magic string, a little-endian header length,
//! a Python dict literal naming the element type, the memory order and the shape, padded so
//! the data starts at a multiple of 64 bytes, then the raw elements. This module writes exactly
//! that, and reads back what it writes and what `numpy.save` writes for the same arrays
//! (versions 1.0 to 3.0, any padding); `tests/it/numpy.rs` checks both directions against NumPy.
//!
//! Kept by hand rather than through `npyz` or `ndarray-npy`, on purpose: both parse the header
//! with `py_literal`, a general Python-literal parser built on `pest`, whose build pulls
//! `pest_derive`, `stacker` and `psm` (assembly compiled through `cc`), `num-bigint` and, for
//! `ndarray-npy`, `ndarray`: about 25 crates and 18 s of a clean build on this project's
//! 2-core machine, to write a 70-byte header of a fixed form and read back two fields of it.
//! The element types here are only `<f4` and `<u4` in C order, which need none of that.

/// A decoded array: element type (`<f4`, `<u4`), shape (rows, columns, channels...) and the
/// elements' bytes in C order.
#[derive(Clone, Debug, PartialEq)]
pub struct Array {
    /// NumPy's type string, e.g. `<f4`.
    pub descr: String,
    /// The dimensions, outermost first.
    pub shape: Vec<usize>,
    /// The raw little-endian elements.
    pub data: Vec<u8>,
}

/// The element types read back (the ones [`crate::output::aov`] writes).
const READABLE: [&str; 2] = ["<f4", "<u4"];

/// The bytes of a `.npy` file (format 1.0) of `data`, elements of type `descr` in C order.
pub fn encode(descr: &str, shape: &[usize], data: &[u8]) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(usize::to_string).collect();
    let shape = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    // Magic (6) + version (2) + length (2) + header + '\n' is a multiple of 64.
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend((header.len() as u16).to_le_bytes());
    out.extend(header.as_bytes());
    out.extend(data);
    out
}

/// Bytes per element of a type string such as `<f4`.
pub fn item_size(descr: &str) -> usize {
    descr.get(2..).and_then(|n| n.parse().ok()).unwrap_or(1)
}

/// Decodes a `.npy` file of little-endian `f4` or `u4` elements in C order with at least two
/// dimensions (an image). The error says what is wrong, for a message naming the file.
pub fn decode(bytes: &[u8]) -> Result<Array, String> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err("not a .npy file".into());
    }
    // Version 1.0: a 2-byte header length; 2.0 and 3.0 (UTF-8 header): 4 bytes.
    let (length_bytes, start): (usize, usize) = match bytes[6] {
        1 => (2, 10),
        2 | 3 => (4, 12),
        v => return Err(format!(".npy format version {v} (1 to 3 are read)")),
    };
    let header_len = bytes
        .get(8..8 + length_bytes)
        .map(|b| b.iter().rev().fold(0usize, |n, &b| n << 8 | usize::from(b)))
        .ok_or("truncated .npy header")?;
    let header = start
        .checked_add(header_len)
        .and_then(|end| bytes.get(start..end))
        .ok_or("truncated .npy header")?;
    let header = std::str::from_utf8(header).map_err(|_| "the .npy header is not text")?;
    let field = |name: &str, open: char, close: char| -> Option<&str> {
        let start = header.find(&format!("'{name}': {open}"))? + name.len() + 4 + open.len_utf8();
        let end = header[start..].find(close)? + start;
        Some(&header[start..end])
    };
    let descr = field("descr", '\'', '\'').ok_or("no 'descr' in the .npy header")?;
    if !READABLE.contains(&descr) {
        return Err(format!("element type {descr} (tiles are <f4 or <u4)"));
    }
    if !header.contains("'fortran_order': False") {
        return Err("Fortran-order arrays are not tiles".into());
    }
    let shape: Vec<usize> = field("shape", '(', ')')
        .ok_or("no 'shape' in the .npy header")?
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().map_err(|_| format!("bad shape entry '{s}'")))
        .collect::<Result<_, _>>()?;
    if shape.len() < 2 {
        return Err(format!("shape {shape:?}: an image has rows and columns"));
    }
    let data = &bytes[start + header_len..];
    let expected = shape
        .iter()
        .try_fold(item_size(descr), |n, &d| n.checked_mul(d))
        .ok_or("shape too large")?;
    if data.len() != expected {
        return Err(format!(
            "shape {shape:?} needs {expected} bytes of data, the file has {}",
            data.len()
        ));
    }
    Ok(Array {
        descr: descr.to_string(),
        shape,
        data: data.to_vec(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_header_is_aligned_and_parsable() {
        let bytes = encode("<f4", &[2, 3], &[0u8; 24]);
        assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00");
        let len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        assert_eq!((10 + len) % 64, 0);
        let header = std::str::from_utf8(&bytes[10..10 + len]).unwrap();
        assert_eq!(
            header.trim_end(),
            "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }"
        );
        assert!(header.ends_with('\n'));
        assert_eq!(bytes.len(), 10 + len + 24);
    }

    #[test]
    fn an_array_round_trips_and_a_short_file_is_refused() {
        let data: Vec<u8> = (0..2 * 3 * 3 * 4).map(|i| i as u8).collect();
        let bytes = encode("<f4", &[2, 3, 3], &data);
        let array = decode(&bytes).unwrap();
        assert_eq!(
            (array.descr.as_str(), &array.shape[..]),
            ("<f4", &[2, 3, 3][..])
        );
        assert_eq!(array.data, data);
        assert!(decode(&bytes[..bytes.len() - 1])
            .unwrap_err()
            .contains("needs 72 bytes"));
        assert!(decode(&bytes[..9]).is_err());
        assert!(decode(b"\x93NUMPY\x01\x00\xff\xff{")
            .unwrap_err()
            .contains("truncated"));
        assert!(decode(b"\x93NUMPY\x01\x00\x02\x00\xff\xfe")
            .unwrap_err()
            .contains("not text"));
    }

    #[test]
    fn numpys_own_header_forms_are_read() {
        // numpy.save pads the shape for in-place growth; version 2.0 has a 4-byte length.
        let header = "{'descr': '<u4', 'fortran_order': False, 'shape': (1, 2), }";
        let padded = format!("{header:<117}\n");
        let mut v1 = b"\x93NUMPY\x01\x00".to_vec();
        v1.extend((padded.len() as u16).to_le_bytes());
        v1.extend(padded.as_bytes());
        v1.extend([1, 0, 0, 0, 2, 0, 0, 0]);
        let mut v2 = b"\x93NUMPY\x02\x00".to_vec();
        v2.extend((padded.len() as u32).to_le_bytes());
        v2.extend(padded.as_bytes());
        v2.extend([1, 0, 0, 0, 2, 0, 0, 0]);
        for bytes in [v1, v2] {
            let array = decode(&bytes).unwrap();
            assert_eq!(array.shape, [1, 2]);
            assert_eq!(array.data, [1, 0, 0, 0, 2, 0, 0, 0]);
        }
        let mut fortran = encode("<f4", &[1, 1], &[0; 4]);
        let at = fortran.windows(5).position(|w| w == b"False").unwrap();
        fortran[at..at + 5].copy_from_slice(b"True ");
        assert!(decode(&fortran).unwrap_err().contains("Fortran"));
        assert!(decode(&encode("<f8", &[1, 1], &[0; 8]))
            .unwrap_err()
            .contains("<f8"));
    }
}
