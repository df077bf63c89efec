//! Opening one chunk: decompressed and CRC-checked whole before any of its records is used, so
//! a damaged chunk contributes nothing, and read with a record length limit (a corrupt inner
//! length must not become an allocation).

use mcap::records::{op, ChunkHeader, Record};
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};

/// Why a chunk could not be used, and whether its CRC was checked on the way.
#[derive(Debug)]
pub(crate) struct ChunkError {
    /// What failed.
    pub reason: String,
}

/// What opening a chunk found.
#[derive(Debug, Default, Clone, Copy)]
pub(crate) struct Opened {
    /// The chunk has a CRC and it was checked.
    pub crc_checked: bool,
}

/// Call `each(opcode, body)` for every record of the chunk whose record body (as the top level
/// framed it) is `body`, in order. A compressed chunk is decompressed and its CRC checked before
/// the first call; an uncompressed one is checked first too. An error after some calls (a chunk
/// without a CRC whose records do not frame) says where.
pub(crate) fn for_each_record(
    body: &[u8],
    limit: u64,
    mut each: impl FnMut(u8, &[u8]),
) -> Result<Opened, ChunkError> {
    let err = |reason: String| ChunkError { reason };
    let (header, data) = match super::parse_record(op::CHUNK, body) {
        Ok(Record::Chunk { header, data }) => (header, data),
        Ok(_) => return Err(err("not a chunk".into())),
        Err(e) => return Err(err(format!("bad chunk header: {e}"))),
    };
    if header.uncompressed_size > limit {
        return Err(err(format!(
            "its header claims {} uncompressed bytes (at most {limit} read)",
            header.uncompressed_size
        )));
    }
    let crc_checked = header.uncompressed_crc != 0;
    if header.compression.is_empty() {
        uncompressed(&header, &data, &mut each)?;
    } else {
        compressed(&header, &data, limit, &mut each)?;
    }
    Ok(Opened { crc_checked })
}

/// An uncompressed chunk's records are top-level records back to back: read them as such
/// (mcap's chunk reader underflows on an uncompressed record that overruns its chunk;
/// docs/robustness.md), after checking the CRC.
fn uncompressed(
    header: &ChunkHeader,
    data: &[u8],
    each: &mut impl FnMut(u8, &[u8]),
) -> Result<(), ChunkError> {
    let err = |reason: String| ChunkError { reason };
    if data.len() as u64 != header.uncompressed_size {
        return Err(err(format!(
            "uncompressed chunk of {} bytes whose header says {}",
            data.len(),
            header.uncompressed_size
        )));
    }
    if header.uncompressed_crc != 0 {
        let calculated = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC).checksum(data);
        if calculated != header.uncompressed_crc {
            return Err(err(format!(
                "CRC mismatch (saved 0x{:08x}, computed 0x{calculated:08x})",
                header.uncompressed_crc
            )));
        }
    }
    let options = LinearReaderOptions::default()
        .with_skip_start_magic(true)
        .with_skip_end_magic(true)
        .with_emit_chunks(true)
        .with_record_length_limit(data.len());
    feed(LinearReader::new_with_options(options), &[data], each)
}

/// A compressed chunk: read as a one-record file by mcap's sans-IO reader, which decompresses
/// it whole and checks its CRC before yielding a record.
fn compressed(
    header: &ChunkHeader,
    data: &[u8],
    limit: u64,
    each: &mut impl FnMut(u8, &[u8]),
) -> Result<(), ChunkError> {
    let mut head = Vec::with_capacity(64);
    head.extend_from_slice(&header.message_start_time.to_le_bytes());
    head.extend_from_slice(&header.message_end_time.to_le_bytes());
    head.extend_from_slice(&header.uncompressed_size.to_le_bytes());
    head.extend_from_slice(&header.uncompressed_crc.to_le_bytes());
    let name = header.compression.as_bytes();
    head.extend_from_slice(&(name.len() as u32).to_le_bytes());
    head.extend_from_slice(name);
    head.extend_from_slice(&(data.len() as u64).to_le_bytes());
    let mut record = Vec::with_capacity(9);
    record.push(op::CHUNK);
    record.extend_from_slice(&((head.len() + data.len()) as u64).to_le_bytes());
    let options = LinearReaderOptions::default()
        .with_skip_start_magic(true)
        .with_skip_end_magic(true)
        .with_prevalidate_chunk_crcs(true)
        .with_record_length_limit(usize::try_from(limit).unwrap_or(usize::MAX));
    feed(LinearReader::new_with_options(options), &[&record, &head, data], each)
}

/// Run `reader` over the concatenation of `parts`, calling `each` for each record.
fn feed(
    mut reader: LinearReader,
    parts: &[&[u8]],
    each: &mut impl FnMut(u8, &[u8]),
) -> Result<(), ChunkError> {
    let mut part = 0;
    let mut at = 0;
    while let Some(event) = reader.next_event() {
        match event {
            Err(e) => return Err(ChunkError { reason: describe(&e) }),
            Ok(LinearReadEvent::ReadRequest(n)) => {
                while part < parts.len() && at == parts[part].len() {
                    part += 1;
                    at = 0;
                }
                let src = parts.get(part).map_or(&[][..], |p| &p[at..]);
                let k = n.min(src.len());
                reader.insert(k).copy_from_slice(&src[..k]);
                reader.notify_read(k);
                at += k;
            }
            Ok(LinearReadEvent::Record { opcode, data }) => each(opcode, data),
        }
    }
    Ok(())
}

fn describe(e: &mcap::McapError) -> String {
    match e {
        mcap::McapError::BadChunkCrc { saved, calculated } => {
            format!("CRC mismatch (saved 0x{saved:08x}, computed 0x{calculated:08x})")
        }
        other => other.to_string(),
    }
}
