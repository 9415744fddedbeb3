//! `inspect --block N`: one block, decoded record by record.

use serde::Serialize;

use oocfmt::records::{Footprint, Node, Sample, Voxel};
use oocfmt::{BlockKind, Reader};

use crate::error::CliError;
use crate::inspect::invalid_block;

#[derive(Serialize)]
pub struct BlockDump {
    pub id: u32,
    pub kind: BlockKind,
    pub codec: oocfmt::CodecId,
    pub level: u16,
    pub offset: u64,
    pub stored_length: u32,
    pub raw_length: u32,
    pub crc: String,
    pub item_count: u32,
    pub content: Content,
}

#[derive(Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Content {
    Treelets(Vec<TreeletDump>),
    Triangles(TriangleDump),
    Proxies(Vec<ProxyDump>),
}

#[derive(Serialize)]
pub struct TreeletDump {
    pub index: usize,
    pub start: usize,
    pub nodes: Vec<NodeDump>,
}

#[derive(Serialize)]
pub struct NodeDump {
    pub pos: usize,
    #[serde(flatten)]
    pub node: NodeJson,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub voxel: Option<Vec<SampleDump>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rlod: Option<RlodDump>,
    /// The LOD entry's part word (spec §6.2), in a file with `PART_IDS` only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub part: Option<u32>,
}

/// An R-LOD record with its bounds decoded for the node's radius (spec §6.4).
#[derive(Serialize)]
pub struct RlodDump {
    pub normal: [f32; 3],
    pub offset: f32,
    pub colour: [u8; 3],
    /// Coverage α and shade σ (spec §6.4), in a file with `LOD_FILTERED` only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coverage: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shade: Option<f32>,
    pub deviation: f32,
    pub expansion: f32,
    pub error_radius: f32,
}

#[derive(Serialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum NodeJson {
    Basic {
        axis: u8,
        split: f32,
        left: Option<usize>,
        right: Option<usize>,
    },
    Lod {
        axis: u8,
        split: f32,
        radius: f32,
        child_block: u32,
        child_treelet: u32,
        left: bool,
        right: bool,
        voxel_offset: u32,
        proxy: Option<u32>,
    },
    Leaf {
        triangle_block: u32,
        first: u16,
        count: u16,
    },
}

#[derive(Serialize)]
pub struct SampleDump {
    pub normal: [f32; 3],
    pub colour: [f32; 3],
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub empty: bool,
    /// A voxel sample's footprint (spec §5.1), where it is not full (σ = α = 1).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shade: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coverage: Option<f32>,
}

impl From<Sample> for SampleDump {
    fn from(s: Sample) -> Self {
        SampleDump {
            normal: s.normal(),
            colour: s.colour(),
            empty: s.is_empty(),
            shade: None,
            coverage: None,
        }
    }
}

impl From<(Sample, Footprint)> for SampleDump {
    fn from((s, f): (Sample, Footprint)) -> Self {
        let full = f.is_full();
        SampleDump {
            shade: (!full).then(|| f.shade_f32()),
            coverage: (!full).then(|| f.coverage_f32()),
            ..SampleDump::from(s)
        }
    }
}

#[derive(Serialize)]
pub struct TriangleDump {
    pub attributes: u16,
    pub primary_count: usize,
    pub list: Vec<u16>,
    pub triangles: Vec<oocfmt::records::triangle::Triangle>,
    pub vertices: Vec<VertexDump>,
}

#[derive(Serialize)]
pub struct VertexDump {
    pub position: [f32; 3],
    #[serde(skip_serializing_if = "Option::is_none")]
    pub normal: Option<[f32; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub colour: Option<[u8; 4]>,
}

#[derive(Serialize)]
pub struct ProxyDump {
    pub node_block: u32,
    pub area: f32,
    pub samples: Vec<SampleDump>,
}

pub fn dump(reader: &Reader, id: u32) -> Result<BlockDump, CliError> {
    if id as usize >= reader.entries().len() {
        return Err(invalid_block(id, reader.entries().len()));
    }
    let block = reader.read_block(id)?;
    let e = block.entry;
    let content = match e.kind {
        BlockKind::Treelet => Content::Treelets(treelets(&block)?),
        BlockKind::Triangle => {
            Content::Triangles(triangles(&block, reader.metadata().triangle_attributes())?)
        }
        BlockKind::Proxy => Content::Proxies(
            block
                .proxies()?
                .into_iter()
                .map(|p| ProxyDump {
                    node_block: p.node_block,
                    area: p.area,
                    samples: p.samples.iter().map(|&s| s.into()).collect(),
                })
                .collect(),
        ),
    };
    Ok(BlockDump {
        id,
        kind: e.kind,
        codec: e.codec,
        level: e.level,
        offset: e.offset,
        stored_length: e.stored_length,
        raw_length: e.raw_length,
        crc: format!("{:08x}", e.crc),
        item_count: e.item_count,
        content,
    })
}

fn treelets(block: &oocfmt::Block) -> Result<Vec<TreeletDump>, CliError> {
    let view = block.treelets()?;
    let mut out: Vec<TreeletDump> = Vec::new();
    view.walk_lods(|t, pos, node, entry| {
        if out.last().is_none_or(|d| d.index != t) {
            out.push(TreeletDump {
                index: t,
                start: pos,
                nodes: Vec::new(),
            });
        }
        let child = |u: u16| (u != 0).then(|| oocfmt::records::TreeletBlock::child_pos(pos, u));
        let mut rlod = None;
        let (json, voxel) = match *node {
            Node::Basic {
                axis,
                split,
                left,
                right,
            } => (
                NodeJson::Basic {
                    axis,
                    split,
                    left: child(left),
                    right: child(right),
                },
                None,
            ),
            Node::Lod {
                axis,
                split,
                radius,
                left_present,
                right_present,
                child_treelet,
                child_block,
                voxel_offset,
                proxy,
            } => {
                let samples = match view.lod_kinds().voxel {
                    true => Some(match view.voxel(voxel_offset)? {
                        v @ Voxel::Single(..) => vec![v.face(0).into()],
                        v @ Voxel::Six(..) => (0..6).map(|f| v.face(f).into()).collect(),
                    }),
                    false => None,
                };
                if view.lod_kinds().rlod {
                    let r = view.rlod(voxel_offset)?;
                    let filtered = view.lod_kinds().filtered;
                    rlod = Some(RlodDump {
                        normal: r.normal,
                        offset: r.offset,
                        colour: r.colour,
                        coverage: filtered.then(|| r.coverage_f32()),
                        shade: filtered.then(|| r.shade_f32()),
                        deviation: r.deviation(radius),
                        expansion: r.expansion(radius),
                        error_radius: r.error_radius(radius),
                    });
                }
                let proxy = (proxy != oocfmt::records::NO_PROXY).then_some(proxy);
                (
                    NodeJson::Lod {
                        axis,
                        split,
                        radius,
                        child_block,
                        child_treelet,
                        left: left_present,
                        right: right_present,
                        voxel_offset,
                        proxy,
                    },
                    samples,
                )
            }
            Node::Leaf {
                count,
                first,
                block,
            } => (
                NodeJson::Leaf {
                    triangle_block: block,
                    first,
                    count,
                },
                None,
            ),
        };
        if let Some(d) = out.last_mut() {
            d.nodes.push(NodeDump {
                pos,
                node: json,
                voxel,
                rlod,
                part: entry.part,
            });
        }
        Ok(())
    })?;
    Ok(out)
}

fn triangles(block: &oocfmt::Block, attrs: u16) -> Result<TriangleDump, CliError> {
    let t = block.triangles(attrs)?;
    let list = (0..t.list_count())
        .map(|i| t.list(i))
        .collect::<Result<_, _>>()?;
    let triangles = (0..t.triangle_count())
        .map(|i| t.triangle(i))
        .collect::<Result<_, _>>()?;
    let vertices = (0..t.vertex_count())
        .map(|i| {
            t.vertex(i).map(|v| VertexDump {
                position: v.position,
                normal: v.normal.map(oocfmt::records::triangle::oct_decode),
                colour: v.colour,
            })
        })
        .collect::<Result<_, _>>()?;
    Ok(TriangleDump {
        attributes: t.attributes(),
        primary_count: t.primary_count(),
        list,
        triangles,
        vertices,
    })
}

/// Text form of a block dump.
pub fn render(d: &BlockDump) -> String {
    use std::fmt::Write;
    let mut o = String::new();
    let _ = writeln!(
        o,
        "block {} {:?} level {} codec {:?}: {} stored bytes at {}, {} raw, crc {}, {} items",
        d.id,
        d.kind,
        d.level,
        d.codec,
        d.stored_length,
        d.offset,
        d.raw_length,
        d.crc,
        d.item_count
    );
    match &d.content {
        Content::Treelets(ts) => {
            for t in ts {
                let _ = writeln!(o, "treelet {} at node byte {}", t.index, t.start);
                for n in &t.nodes {
                    let _ = writeln!(
                        o,
                        "  {:>6}: {}",
                        n.pos,
                        serde_json::to_string(&n.node).unwrap_or_default()
                    );
                    if let Some(v) = &n.voxel {
                        let _ = writeln!(
                            o,
                            "          voxel {}",
                            serde_json::to_string(v).unwrap_or_default()
                        );
                    }
                    if let Some(r) = &n.rlod {
                        let _ = writeln!(
                            o,
                            "          rlod {}",
                            serde_json::to_string(r).unwrap_or_default()
                        );
                    }
                    if let Some(p) = n.part {
                        let _ = writeln!(o, "          part {p}");
                    }
                }
            }
        }
        Content::Triangles(t) => {
            let _ = writeln!(
                o,
                "attributes {:#x}, {} primaries",
                t.attributes, t.primary_count
            );
            let _ = writeln!(o, "list {:?}", t.list);
            for (i, tri) in t.triangles.iter().enumerate() {
                let _ = writeln!(
                    o,
                    "  triangle {i}: vertices {:?}{}{}",
                    tri.v,
                    tri.material
                        .map(|m| format!(" material {m}"))
                        .unwrap_or_default(),
                    tri.part.map(|p| format!(" part {p}")).unwrap_or_default()
                );
            }
            for (i, v) in t.vertices.iter().enumerate() {
                let _ = writeln!(
                    o,
                    "  vertex {i}: {}",
                    serde_json::to_string(v).unwrap_or_default()
                );
            }
        }
        Content::Proxies(ps) => {
            for (i, p) in ps.iter().enumerate() {
                let _ = writeln!(
                    o,
                    "  proxy {i}: node block {}, area {}",
                    p.node_block, p.area
                );
            }
        }
    }
    o
}
