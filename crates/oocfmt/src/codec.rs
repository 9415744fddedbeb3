//! Block compression: none, LZ4 (block format) and zstd, behind one enum (spec §4).

use crate::directory::CodecId;
use crate::error::{Code, Error, Result};

/// A codec with its settings, as a writer chooses it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Codec {
    /// Store blocks as they are (codec id 0).
    None,
    /// One LZ4 block per block, without the LZ4 frame (codec id 1): fast to decode, the default.
    #[default]
    Lz4,
    /// zstd at a level in 1 ..= 22.
    Zstd(i32),
}

impl Codec {
    /// The zstd level that `zstd` without `:LEVEL` means (zstd's own default).
    pub const DEFAULT_ZSTD_LEVEL: i32 = 3;

    /// The codec id this codec writes into directory entries when it makes a block smaller.
    pub fn id(self) -> CodecId {
        match self {
            Codec::None => CodecId::None,
            Codec::Lz4 => CodecId::Lz4,
            Codec::Zstd(_) => CodecId::Zstd,
        }
    }

    /// Parses `none`, `lz4`, `zstd` or `zstd:LEVEL`.
    pub fn parse(s: &str) -> Result<Codec> {
        match s {
            "none" => Ok(Codec::None),
            "lz4" => Ok(Codec::Lz4),
            "zstd" => Ok(Codec::Zstd(Self::DEFAULT_ZSTD_LEVEL)),
            _ => {
                let level = s
                    .strip_prefix("zstd:")
                    .and_then(|l| l.parse::<i32>().ok())
                    .filter(|l| (1..=22).contains(l))
                    .ok_or_else(|| {
                        Error::parameter(format!("codec `{s}`: expected none, lz4, zstd or zstd:LEVEL with LEVEL in 1..=22"))
                    })?;
                Ok(Codec::Zstd(level))
            }
        }
    }

    /// Encodes `raw` and returns what to store: the compressed bytes when they are smaller,
    /// else the raw bytes under codec none (spec §4).
    pub fn encode(self, raw: &[u8]) -> Result<(CodecId, Vec<u8>)> {
        let packed = match self {
            Codec::None => None,
            Codec::Lz4 => Some(lz4_flex::block::compress(raw)),
            Codec::Zstd(level) => Some(zstd::bulk::compress(raw, level).map_err(Error::from)?),
        };
        match packed {
            Some(p) if p.len() < raw.len() => Ok((self.id(), p)),
            _ => Ok((CodecId::None, raw.to_vec())),
        }
    }
}

/// Decodes `stored` into `out`, whose length is the raw length from the directory. Any other
/// output length is an error, whatever the compressed data claims.
pub fn decode_into(codec: CodecId, stored: &[u8], out: &mut [u8]) -> Result<()> {
    let fail = |detail: String| Error::malformed(Code::BlockDecompress, detail);
    let produced = match codec {
        CodecId::None => {
            if stored.len() != out.len() {
                return Err(fail(format!(
                    "{} stored bytes for {} raw bytes",
                    stored.len(),
                    out.len()
                )));
            }
            out.copy_from_slice(stored);
            out.len()
        }
        CodecId::Lz4 => {
            lz4_flex::block::decompress_into(stored, out).map_err(|e| fail(format!("lz4: {e}")))?
        }
        CodecId::Zstd => {
            check_zstd_frame(stored, out.len()).map_err(fail)?;
            zstd::bulk::decompress_to_buffer(stored, out).map_err(|e| fail(format!("zstd: {e}")))?
        }
    };
    if produced != out.len() {
        return Err(fail(format!(
            "{} produced {produced} bytes, the directory says {}",
            codec.name(),
            out.len()
        )));
    }
    Ok(())
}

/// The zstd frame magic, little-endian (RFC 8878 §3.1.1).
const ZSTD_MAGIC: [u8; 4] = [0x28, 0xb5, 0x2f, 0xfd];

/// The frame rules of spec §4, checked here so that they hold whatever the zstd library
/// accepts (it decodes skippable and concatenated frames, and frames without a content size):
/// the stored bytes are exactly one zstd frame, with no dictionary, whose header states a
/// content size equal to the raw length.
fn check_zstd_frame(stored: &[u8], raw_length: usize) -> std::result::Result<(), String> {
    if stored.get(..4) != Some(&ZSTD_MAGIC[..]) {
        return Err("zstd: the stored bytes do not start with a zstd frame's magic".into());
    }
    let descriptor = stored
        .get(4)
        .copied()
        .ok_or("zstd: the frame header is cut short")?;
    let fcs_flag = descriptor >> 6;
    let single_segment = descriptor & 0x20 != 0;
    let dict_flag = descriptor & 0x03;
    if dict_flag != 0 {
        return Err("zstd: the frame names a dictionary".into());
    }
    let fcs_len = match (fcs_flag, single_segment) {
        (0, false) => {
            return Err("zstd: the frame header does not state the content size".into());
        }
        (0, true) => 1,
        (1, _) => 2,
        (2, _) => 4,
        _ => 8,
    };
    // The field follows the descriptor and, without the single-segment flag, the window byte.
    let at = 5 + usize::from(!single_segment);
    let field = stored
        .get(at..at + fcs_len)
        .ok_or("zstd: the frame header is cut short")?;
    let mut le = [0u8; 8];
    le.get_mut(..fcs_len)
        .ok_or("zstd: content size field")?
        .copy_from_slice(field);
    let size = u64::from_le_bytes(le) + if fcs_len == 2 { 256 } else { 0 };
    if size != raw_length as u64 {
        return Err(format!(
            "zstd: the frame states {size} content bytes, the directory says {raw_length}"
        ));
    }
    match zstd::zstd_safe::find_frame_compressed_size(stored) {
        Ok(n) if n == stored.len() => Ok(()),
        Ok(n) => Err(format!(
            "zstd: the frame ends at byte {n} of {} stored bytes",
            stored.len()
        )),
        Err(code) => Err(format!("zstd: {}", zstd::zstd_safe::get_error_name(code))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_accepts_the_documented_forms() {
        assert_eq!(Codec::parse("zstd:19").ok(), Some(Codec::Zstd(19)));
        assert!(Codec::parse("zstd:0").is_err());
        assert!(Codec::parse("gzip").is_err());
    }

    #[test]
    fn every_codec_round_trips_and_never_grows() {
        let raw: Vec<u8> = (0..5000u32).map(|i| (i % 7) as u8).collect();
        let noise: Vec<u8> = (0..5000u32)
            .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
            .collect();
        for codec in [Codec::None, Codec::Lz4, Codec::Zstd(3)] {
            for input in [&raw, &noise] {
                let (id, stored) = codec.encode(input).unwrap_or_default_pair();
                assert!(stored.len() <= input.len());
                let mut out = vec![0; input.len()];
                assert!(decode_into(id, &stored, &mut out).is_ok());
                assert_eq!(&out, input);
            }
        }
    }

    #[test]
    fn a_short_claim_is_refused() {
        let (id, stored) = Codec::Lz4.encode(&[7u8; 4096]).unwrap_or_default_pair();
        let mut out = vec![0; 4095];
        assert!(decode_into(id, &stored, &mut out).is_err());
        let mut out = vec![0; 4097];
        assert!(decode_into(id, &stored, &mut out).is_err());
    }

    trait OrDefault {
        fn unwrap_or_default_pair(self) -> (CodecId, Vec<u8>);
    }
    impl OrDefault for Result<(CodecId, Vec<u8>)> {
        fn unwrap_or_default_pair(self) -> (CodecId, Vec<u8>) {
            match self {
                Ok(p) => p,
                Err(e) => panic!("encode failed: {e}"),
            }
        }
    }
}
