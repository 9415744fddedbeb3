//! Block compression: none, LZ4 (block format) and zstd, behind one enum (spec §4).

use crate::directory::CodecId;
use crate::error::{Code, Error, Result};

/// A codec with its settings, as a writer chooses it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Codec {
    None,
    #[default]
    Lz4,
    /// zstd at a level in 1 ..= 22.
    Zstd(i32),
}

impl Codec {
    pub const DEFAULT_ZSTD_LEVEL: i32 = 3;

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
    let produced =
        match codec {
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
            CodecId::Lz4 => lz4_flex::block::decompress_into(stored, out)
                .map_err(|e| fail(format!("lz4: {e}")))?,
            CodecId::Zstd => zstd::bulk::decompress_to_buffer(stored, out)
                .map_err(|e| fail(format!("zstd: {e}")))?,
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
