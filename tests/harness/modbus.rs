//! Modbus PDUs written by hand, for the tests that speak to plcd's Modbus servers with raw
//! frames (over TCP and over a serial line): requests built, answers taken apart.

/// A read request: FC 1–4 of `count` from `start`.
pub fn read(fc: u8, start: u16, count: u16) -> Vec<u8> {
    let mut p = vec![fc];
    p.extend_from_slice(&start.to_be_bytes());
    p.extend_from_slice(&count.to_be_bytes());
    p
}

/// FC 16: `values` from `start`.
pub fn write_registers(start: u16, values: &[u16]) -> Vec<u8> {
    let mut p = vec![16];
    p.extend_from_slice(&start.to_be_bytes());
    p.extend_from_slice(&(values.len() as u16).to_be_bytes());
    p.push(2 * values.len() as u8);
    for v in values {
        p.extend_from_slice(&v.to_be_bytes());
    }
    p
}

/// FC 15: `values` from `start`, packed eight to a byte.
pub fn write_coils(start: u16, values: &[bool]) -> Vec<u8> {
    let mut p = vec![15];
    p.extend_from_slice(&start.to_be_bytes());
    p.extend_from_slice(&(values.len() as u16).to_be_bytes());
    let mut packed = vec![0u8; values.len().div_ceil(8)];
    for (i, on) in values.iter().enumerate() {
        packed[i / 8] |= u8::from(*on) << (i % 8);
    }
    p.push(packed.len() as u8);
    p.extend_from_slice(&packed);
    p
}

/// Registers of an answer's data, big-endian pairs.
pub fn words(bytes: &[u8]) -> Vec<u16> {
    bytes.chunks(2).map(|c| u16::from_be_bytes([c[0], c[1]])).collect()
}

/// The first `count` bits of an answer's packed data.
pub fn bits(bytes: &[u8], count: usize) -> Vec<bool> {
    (0..count).map(|i| bytes[i / 8] >> (i % 8) & 1 == 1).collect()
}

/// An exception response to `fc` with `code`.
pub fn exception(fc: u8, code: u8) -> Vec<u8> {
    vec![fc | 0x80, code]
}
