//! The build settings `convert` and `plan` share: the flags that decide what a container holds.
//! A plan records them as flags, so every subset and the merge parse the very same settings.

use clap::{Parser, ValueEnum};

use oocfmt::records::LodKinds;
use oocfmt::{Codec, WriteOptions};
use oocfmt_build::convert::{ConvertOptions, InputFormat, MIN_MEM_LIMIT};
use oocfmt_build::kdtree::KdBuildOptions;
use oocfmt_build::layout::LayoutOptions;
use oocfmt_build::report::total_memory;
use oocfmt_build::Interrupt;
use oocfmt_meshio::import::gltf::GltfOptions;
use oocfmt_meshio::import::obj::ObjOptions;
use oocfmt_meshio::import::Recentre;

use crate::args::{self, LodKindsArg};
use crate::error::CliError;

#[derive(clap::Args, Clone, Debug, PartialEq)]
pub struct BuildArgs {
    /// The inputs' format, whatever their names (standard input has none): obj, ply, stl or
    /// gltf (not from standard input)
    #[arg(long, value_enum)]
    pub format: Option<FormatArg>,
    /// Block codec: none, lz4, zstd or zstd:LEVEL (none is what a memory-mapped reader wants)
    #[arg(long, default_value = "lz4", value_parser = args::parse_codec)]
    pub codec: Codec,
    /// Block size in bytes: a power of two from 4096 to 1048576
    #[arg(long, default_value_t = 65536)]
    pub block_size: u64,
    /// Most triangles per kd-tree leaf (1..=4095)
    #[arg(long, default_value_t = 8)]
    pub max_leaf: u32,
    /// Node levels per treelet; every this-many levels holds the LOD voxels
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(1..=8))]
    pub treelet_height: u8,
    /// LOD representations to store in the LOD nodes: rlod (planes, Yoon et al. 2006), voxel
    /// (Áfra 2012) or both, in core or out of core alike
    #[arg(long, value_enum, default_value = "rlod")]
    pub lod: LodKindsArg,
    /// Write opaque, unfiltered LOD records as version 1.1 did (no shade or coverage, spec
    /// §5.1): for 1.1 readers, and to measure what pre-filtering gains
    #[arg(long)]
    pub unfiltered: bool,
    /// Refuse the first bad triangle (NaN, out-of-range index, zero area) instead of dropping it
    #[arg(long)]
    pub strict: bool,
    /// Memory the build may use, e.g. 2G, 512M, at least 16M (default: half the physical
    /// memory). A larger scene is built out of core, in chunks that fit
    #[arg(long, value_parser = parse_mem_limit)]
    pub mem_limit: Option<u64>,
    /// Store positions relative to an origin: none (positions exactly as read), auto (near
    /// the centre of the input's bounds; one more pass over the input, so not with `-`) or
    /// X,Y,Z. For models far from zero, where f32 positions would lose precision; the report
    /// gives the error
    #[arg(
        long,
        default_value = "none",
        value_name = "auto|none|X,Y,Z",
        allow_hyphen_values = true
    )]
    pub recentre: Recentre,
    /// glTF: import every scene, not only the default one
    #[arg(long)]
    pub all_scenes: bool,
}

/// `--format`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum FormatArg {
    Obj,
    Ply,
    Stl,
    Gltf,
}

impl From<FormatArg> for InputFormat {
    fn from(f: FormatArg) -> InputFormat {
        match f {
            FormatArg::Obj => InputFormat::Obj,
            FormatArg::Ply => InputFormat::Ply,
            FormatArg::Stl => InputFormat::Stl,
            FormatArg::Gltf => InputFormat::Gltf,
        }
    }
}

/// A `--mem-limit`: a size of at least [`MIN_MEM_LIMIT`].
fn parse_mem_limit(s: &str) -> Result<u64, String> {
    let v = args::parse_byte_size(s)?;
    if v < MIN_MEM_LIMIT {
        return Err(format!(
            "`{s}`: below the minimum of {}M (the importers and one chunk of the out-of-core build need that much)",
            MIN_MEM_LIMIT >> 20
        ));
    }
    Ok(v)
}

/// The settings alone, to parse a plan's record of them.
#[derive(Parser)]
#[command(name = "plan settings", no_binary_name = true)]
struct Settings {
    #[command(flatten)]
    build: BuildArgs,
}

impl BuildArgs {
    /// The settings when no flag is given.
    pub fn defaults() -> Result<BuildArgs, CliError> {
        BuildArgs::from_settings(&[])
    }

    /// Parses settings recorded by [`BuildArgs::settings`].
    pub fn from_settings(settings: &[String]) -> Result<BuildArgs, CliError> {
        Settings::try_parse_from(settings)
            .map(|s| s.build)
            .map_err(|e| CliError::Usage(format!("the plan's settings: {}", e.kind())))
    }

    /// Every setting as flags, the memory limit resolved to bytes, so that a subset built on
    /// any machine uses the chunk budget of the machine that planned it.
    pub fn settings(&self) -> Vec<String> {
        let mut s: Vec<String> = Vec::new();
        let mut flag = |name: &str, value: String| {
            s.push(format!("--{name}"));
            s.push(value);
        };
        if let Some(f) = self.format {
            flag("format", value_name(f));
        }
        let codec = match self.codec {
            Codec::None => "none".to_string(),
            Codec::Lz4 => "lz4".to_string(),
            Codec::Zstd(level) => format!("zstd:{level}"),
        };
        flag("codec", codec);
        flag("block-size", self.block_size.to_string());
        flag("max-leaf", self.max_leaf.to_string());
        flag("treelet-height", self.treelet_height.to_string());
        flag("lod", value_name(self.lod));
        flag("mem-limit", self.mem_limit().to_string());
        flag("recentre", self.recentre.to_string());
        for (on, name) in [
            (self.unfiltered, "--unfiltered"),
            (self.strict, "--strict"),
            (self.all_scenes, "--all-scenes"),
        ] {
            if on {
                s.push(name.to_string());
            }
        }
        s
    }

    /// `--mem-limit`, or half the physical memory (4 GiB where it is unknown).
    pub fn mem_limit(&self) -> u64 {
        self.mem_limit
            .unwrap_or_else(|| total_memory().map_or(4 << 30, |m| m / 2))
    }

    /// The library's options for these settings.
    pub fn options(&self, tmp_dir: Option<std::path::PathBuf>) -> Result<ConvertOptions, CliError> {
        let lod = LodKinds::from(self.lod);
        let write = WriteOptions {
            codec: self.codec,
            lod: if self.unfiltered { lod } else { lod.filtered() },
            ..WriteOptions::default()
        }
        .with_block_size(self.block_size)?;
        Ok(ConvertOptions {
            layout: LayoutOptions {
                write,
                treelet_height: self.treelet_height,
                ..LayoutOptions::default()
            },
            kd: KdBuildOptions {
                max_leaf_triangles: self.max_leaf,
                ..KdBuildOptions::default()
            },
            strict: self.strict,
            mem_limit: self.mem_limit(),
            obj: ObjOptions::default(),
            ply: Default::default(),
            gltf: GltfOptions {
                all_scenes: self.all_scenes,
                ..GltfOptions::default()
            },
            recentre: self.recentre,
            tmp_dir,
            format: self.format.map(InputFormat::from),
            interrupt: Interrupt::new(),
        })
    }
}

/// A value enum's name on the command line.
fn value_name<T: ValueEnum>(v: T) -> String {
    v.to_possible_value()
        .map(|p| p.get_name().to_string())
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_parse_back_to_themselves() -> Result<(), CliError> {
        let mut a = BuildArgs::defaults()?;
        assert_eq!(
            BuildArgs::from_settings(&a.settings())?.mem_limit,
            Some(a.mem_limit())
        );
        a.codec = Codec::Zstd(7);
        a.format = Some(FormatArg::Ply);
        a.lod = LodKindsArg::Both;
        a.mem_limit = Some(123 << 20);
        a.recentre = Recentre::At([1.5, -2.0, 1e-300]);
        a.strict = true;
        a.unfiltered = true;
        a.all_scenes = true;
        a.treelet_height = 4;
        a.max_leaf = 3;
        a.block_size = 1 << 14;
        assert_eq!(BuildArgs::from_settings(&a.settings())?, a);
        assert!(BuildArgs::from_settings(&["--bogus".into()]).is_err());
        Ok(())
    }
}
