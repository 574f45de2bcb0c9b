//! The one writer of ROS 1 bag records, for the bags tests and the xtask write (slam-io reads
//! bags only). xtask compiles this file as a module of its own (`#[path]`) rather than
//! depend on slam-io, so it holds plain functions only: no paths into the crate.

/// One ROS 1 bag record (format 2.0, wiki.ros.org/Bags/Format/2.0): the header (each field
/// `name=value` after its u32 little-endian length, the whole after its length), then the
/// data after its length. Fields and data over 4 GiB are not representable (u32 lengths).
pub fn ros1_record(fields: &[(&str, &[u8])], data: &[u8]) -> Vec<u8> {
    let mut r = ros1_record_head(fields, data.len() as u32);
    r.extend(data);
    r
}

/// The record of [`ros1_record`] up to its data, for a writer that streams `data_len`
/// bytes of data after it.
pub fn ros1_record_head(fields: &[(&str, &[u8])], data_len: u32) -> Vec<u8> {
    let mut h = Vec::new();
    for (n, v) in fields {
        h.extend((n.len() as u32 + 1 + v.len() as u32).to_le_bytes());
        h.extend(n.as_bytes());
        h.push(b'=');
        h.extend(*v);
    }
    let mut r = (h.len() as u32).to_le_bytes().to_vec();
    r.extend(h);
    r.extend(data_len.to_le_bytes());
    r
}
