//! NumPy's `.npy` format (version 1.0) for the arrays an analysis writes beside its report
//! (`bench diagnose --scan-dir`), readable with `numpy.load`.

/// A one-dimensional little-endian f64 array as a `.npy` file's bytes.
pub fn npy_f64(values: &[f64]) -> Vec<u8> {
    let mut header =
        format!("{{'descr': '<f8', 'fortran_order': False, 'shape': ({},), }}", values.len());
    // Magic (6) + version (2) + header length (2) + header + '\n', padded to a multiple of 64.
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + 8 * values.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    // The header is under 128 bytes: its length fits a u16.
    out.extend_from_slice(&u16::try_from(header.len()).unwrap_or(u16::MAX).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_header_is_aligned_and_the_values_follow_little_endian() {
        let bytes = npy_f64(&[1.0, -2.5]);
        assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00");
        let header_len = usize::from(u16::from_le_bytes([bytes[8], bytes[9]]));
        assert_eq!((10 + header_len) % 64, 0);
        let header = std::str::from_utf8(&bytes[10..10 + header_len]).expect("ascii");
        assert!(header.starts_with("{'descr': '<f8', 'fortran_order': False, 'shape': (2,), }"));
        assert!(header.ends_with('\n'));
        let data = &bytes[10 + header_len..];
        assert_eq!(data.len(), 16);
        assert_eq!(f64::from_le_bytes(data[..8].try_into().expect("8")), 1.0);
        assert_eq!(f64::from_le_bytes(data[8..].try_into().expect("8")), -2.5);
    }
}
