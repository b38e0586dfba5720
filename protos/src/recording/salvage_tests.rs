//! Unfinished and damaged recordings: what the readers keep, and that no length field is trusted.

use super::*;

/// A recording of `n` messages (log time = index) in chunks of about `chunk_bytes`, written by
/// the `mcap` crate itself, and the byte range and message count of each chunk.
fn small_chunked(n: u64, chunk_bytes: u64) -> (Vec<u8>, Vec<(u64, u64, u64)>) {
    small_chunked_with(n, chunk_bytes, Some(mcap::Compression::Zstd))
}

/// [`small_chunked`] with the chunks compressed by `compression`.
fn small_chunked_with(
    n: u64,
    chunk_bytes: u64,
    compression: Option<mcap::Compression>,
) -> (Vec<u8>, Vec<(u64, u64, u64)>) {
    small_chunked_opts(n, mcap::WriteOptions::new().compression(compression).chunk_size(Some(chunk_bytes)))
}

/// [`small_chunked`] written with `options`.
fn small_chunked_opts(n: u64, options: mcap::WriteOptions) -> (Vec<u8>, Vec<(u64, u64, u64)>) {
    let mut w = options.create(std::io::Cursor::new(Vec::new())).expect("writer");
    let schema = w.add_schema("risktwin.v1.VehicleState", "protobuf", b"schema").expect("schema");
    let channel = w.add_channel(schema, "risktwin/v1/s/veh-1/state", "protobuf", &BTreeMap::new()).expect("channel");
    for seq in 0..n {
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: seq as u32,
            log_time: seq,
            publish_time: seq,
        };
        w.write_to_known_channel(&header, &[seq as u8; 40]).expect("message");
    }
    w.finish().expect("finish");
    let bytes = w.into_inner().into_inner();
    let summary = mcap::Summary::read(&bytes).expect("summary").expect("a summary");
    let chunks = summary
        .chunk_indexes
        .iter()
        .map(|c| {
            (c.chunk_start_offset, c.chunk_start_offset + c.chunk_length, c.message_end_time - c.message_start_time + 1)
        })
        .collect();
    (bytes, chunks)
}

/// Every message the cursor yields, and whether it ended in an error.
fn drain(bytes: &[u8]) -> (Vec<u64>, Option<String>) {
    let mut cursor = MessageCursor::new(bytes);
    let mut times = Vec::new();
    while let Some(m) = cursor.next_message() {
        match m {
            Ok(m) => times.push(m.log_time_ns),
            Err(e) => return (times, Some(e.to_string())),
        }
    }
    (times, None)
}

#[test]
fn a_file_cut_anywhere_gives_the_messages_of_its_complete_chunks() {
    let (bytes, chunks) = small_chunked(60, 400);
    assert!(chunks.len() >= 4, "several chunks: {chunks:?}");
    for cut in 0..bytes.len() {
        let complete: u64 = chunks.iter().filter(|c| c.1 <= cut as u64).map(|c| c.2).sum();
        let (times, error) = drain(&bytes[..cut]);
        if complete == 0 {
            assert!(error.is_some(), "cut at {cut}: nothing complete is an error, got {} messages", times.len());
            continue;
        }
        assert_eq!(error, None, "cut at {cut}: the tail is not an error");
        assert_eq!(times, (0..complete).collect::<Vec<_>>(), "cut at {cut}");
    }
}

#[test]
fn lz4_and_uncompressed_chunks_of_other_writers_read_like_zstd_ones() {
    for compression in [Some(mcap::Compression::Lz4), None] {
        let (bytes, chunks) = small_chunked_with(60, 400, compression);
        let (times, error) = drain(&bytes);
        assert_eq!((times, error), ((0..60).collect(), None), "{compression:?}");
        // Cut inside the third chunk: the first two chunks' messages, the rest a tail.
        let (times, error) = drain(&bytes[..chunks[2].1 as usize - 1]);
        assert_eq!(error, None, "{compression:?}");
        assert_eq!(times.len() as u64, chunks[0].2 + chunks[1].2, "{compression:?}");
    }
}

#[test]
fn a_chunk_without_a_crc_that_does_not_parse_yields_none_of_its_messages() {
    // Uncompressed chunks without a CRC (0: "not computed", which other writers may write).
    let options = mcap::WriteOptions::new().compression(None).calculate_chunk_crcs(false).chunk_size(Some(400));
    let (bytes, chunks) = small_chunked_opts(60, options);
    let records_at = |chunk_start: u64| {
        // Chunk body: start, end, uncompressed size, crc, compression (length-prefixed), records length.
        let body = chunk_start as usize + 9;
        let compression_len = u32::from_le_bytes(bytes[body + 28..body + 32].try_into().unwrap()) as usize;
        body + 32 + compression_len + 8
    };
    let crc_at = chunks[1].0 as usize + 9 + 24;
    assert_eq!(bytes[crc_at..crc_at + 4], [0, 0, 0, 0], "no CRC written");
    // The second chunk's third record claims a length past the chunk's end.
    let mut at = records_at(chunks[1].0);
    for _ in 0..2 {
        at += 9 + u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
    }
    let mut damaged = bytes.clone();
    damaged[at + 1 + 4] ^= 0x01;
    let (times, error) = drain(&damaged);
    assert!(error.is_some_and(|e| e.contains(&format!("chunk at byte {}", chunks[1].0))), "an error naming the chunk");
    assert_eq!(times.len() as u64, chunks[0].2, "the first chunk's messages, none of the damaged one's: {times:?}");
    assert_eq!(drain(&bytes), ((0..60).collect(), None), "undamaged, it reads whole");
}

#[test]
fn damage_in_the_middle_of_a_finished_file_is_an_error_not_a_tail() {
    let (bytes, chunks) = small_chunked(60, 400);
    // The second chunk's opcode turned into a reserved one: unreadable from there, but the file
    // goes on to its footer and end magic, so it was finished, not cut short.
    let mut damaged = bytes.clone();
    damaged[chunks[1].0 as usize] = 0x20;
    let (times, error) = drain(&damaged);
    let error = error.expect("an error");
    assert!(error.contains(&format!("at byte {}", chunks[1].0)) && error.contains("damaged"), "{error}");
    assert_eq!(times.len() as u64, chunks[0].2, "the messages before the damage");
    // The same file cut before its end magic is an unfinished one: a tail.
    let (times, error) = drain(&damaged[..damaged.len() - 1]);
    assert_eq!((times.len() as u64, error), (chunks[0].2, None));
}

#[test]
fn trailing_garbage_after_complete_chunks_is_a_tail_not_an_error() {
    let (bytes, chunks) = small_chunked(60, 400);
    let mut cut = bytes[..chunks[1].1 as usize].to_vec();
    cut.extend_from_slice(b"garbage!garbage!");
    let (times, error) = drain(&cut);
    assert_eq!(error, None);
    assert_eq!(times.len() as u64, chunks[0].2 + chunks[1].2);
}

#[test]
fn a_flipped_length_byte_is_an_error_not_an_allocation() {
    let (bytes, chunks) = small_chunked(60, 400);
    // The top byte of the second chunk's record length: it claims 72 PB.
    let mut flipped = bytes.clone();
    flipped[chunks[1].0 as usize + 1 + 7] ^= 0x01;
    let (times, error) = drain(&flipped);
    let error = error.expect("an error");
    let cap = format!("record at byte {} claims 72057594037928", chunks[1].0);
    assert!(error.contains(&cap) && error.contains("above the 268435456-byte cap"), "{error}");
    assert_eq!(times.len() as u64, chunks[0].2, "the messages before the damage");
    // The top byte of the second chunk's uncompressed size (after start and end time).
    let mut flipped = bytes.clone();
    flipped[chunks[1].0 as usize + 9 + 16 + 7] ^= 0x01;
    assert!(drain(&flipped).1.is_some(), "a chunk claiming 72 PB uncompressed is an error");
}

#[test]
fn no_single_flipped_byte_panics_or_aborts() {
    let (bytes, _) = small_chunked(12, 200);
    for at in 0..bytes.len() {
        for mask in [0x01u8, 0x80, 0xff] {
            let mut damaged = bytes.clone();
            damaged[at] ^= mask;
            let _ = drain(&damaged);
        }
    }
}

#[test]
fn a_recorder_that_never_finishes_keeps_what_it_flushed() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("killed.mcap");
    let file = std::fs::File::create(&path).expect("create");
    let mut rec = Recorder::new(std::io::BufWriter::new(file)).expect("recorder");
    let channel = rec.channel("risktwin/v1/s/veh-1/state", "risktwin.v1.VehicleState").expect("channel");
    for t in 0..50 {
        rec.write(channel, t, t, &[7; 100]).expect("write");
    }
    rec.flush().expect("flush");
    for t in 50..60 {
        rec.write(channel, t, t, &[7; 100]).expect("write");
    }
    // What a kill leaves: no finish, no drop (which would finish the file).
    std::mem::forget(rec);
    let bytes = std::fs::read(&path).expect("read");
    let (kept, unfinished) = salvage_messages(&bytes).expect("salvaged");
    assert_eq!(kept.iter().map(|m| m.log_time_ns).collect::<Vec<_>>(), (0..50).collect::<Vec<_>>());
    let unfinished = unfinished.expect("reported as unfinished");
    assert_eq!((unfinished.messages, unfinished.last_log_time_ns), (50, 49));
    assert_eq!(unfinished.tail.at_byte + unfinished.tail.unreadable_bytes, bytes.len() as u64);
    assert!(read_messages(&bytes).is_err(), "the strict reader refuses it");
}

#[test]
fn a_chunk_claiming_more_than_the_chunk_cap_decompressed_is_refused_before_allocation() {
    let (bytes, chunks) = small_chunked(60, 400);
    let size_at = chunks[1].0 as usize + 9 + 16;
    let mut claimed = bytes.clone();
    claimed[size_at..size_at + 8].copy_from_slice(&(CHUNK_UNCOMPRESSED_CAP + 1).to_le_bytes());
    let (times, error) = drain(&claimed);
    let error = error.expect("an error");
    assert!(error.contains(&format!("chunk at byte {}", chunks[1].0)), "{error}");
    assert!(error.contains("above the 67108864-byte cap"), "{error}");
    assert_eq!(times.len() as u64, chunks[0].2, "the messages before the damage");
}

#[test]
fn a_record_above_the_cap_names_the_cap_and_says_only_when_the_file_is_shorter() {
    let error =
        |file_len| RecordingError::RecordTooLong { at_byte: 8, claimed: RECORD_LENGTH_CAP + 1, file_len }.to_string();
    assert_eq!(
        error(Some(1 << 30)),
        "record at byte 8 claims 268435457 bytes, above the 268435456-byte cap (the file has 1073741824)"
    );
    assert_eq!(
        error(Some(100)),
        "record at byte 8 claims 268435457 bytes, above the 268435456-byte cap (the file has only 100)"
    );
    assert_eq!(error(None), "record at byte 8 claims 268435457 bytes, above the 268435456-byte cap");
}
