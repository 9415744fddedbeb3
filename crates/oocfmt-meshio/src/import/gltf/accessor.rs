//! Accessors, checked and read here rather than through the gltf crate's readers, which
//! panic on `count` 0, on sparse accessors with `count` 0, on a `byteStride` below the element
//! size, and (in debug builds) on integer positions. Every range is checked against the
//! declared lengths of views and buffers before any byte is read, and reads go through
//! bounds-checked slices, so no accessor can make the importer panic or allocate.

use gltf::json;
use gltf::json::accessor::{ComponentType, Type};
use gltf::json::validation::Checked;

use super::buffers::Buffers;

/// What an accessor is used for; each use allows its own types (glTF 2.0 §3.7.2.1 and
/// KHR_mesh_quantization).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Role {
    Position,
    Normal,
    Colour,
    Indices,
}

/// What the document allows beyond the core specification, and how far counts may go.
#[derive(Clone, Copy, Debug)]
pub(super) struct Rules {
    /// KHR_mesh_quantization is used: integer positions and normals are valid.
    pub quantization: bool,
    /// An accessor without a buffer view stands for `count` zeros; it may not stand for more
    /// bytes than the buffers may hold in all.
    pub max_bytes: u64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Comp {
    I8,
    U8,
    I16,
    U16,
    U32,
    F32,
}

impl Comp {
    fn of(c: ComponentType) -> Comp {
        match c {
            ComponentType::I8 => Comp::I8,
            ComponentType::U8 => Comp::U8,
            ComponentType::I16 => Comp::I16,
            ComponentType::U16 => Comp::U16,
            ComponentType::U32 => Comp::U32,
            ComponentType::F32 => Comp::F32,
        }
    }

    fn size(self) -> u64 {
        match self {
            Comp::I8 | Comp::U8 => 1,
            Comp::I16 | Comp::U16 => 2,
            Comp::U32 | Comp::F32 => 4,
        }
    }
}

fn components(t: Type) -> usize {
    match t {
        Type::Scalar => 1,
        Type::Vec2 => 2,
        Type::Vec3 => 3,
        Type::Vec4 | Type::Mat2 => 4,
        Type::Mat3 => 9,
        Type::Mat4 => 16,
    }
}

/// A run of elements in one buffer: element `i` starts at `offset + i * stride`, and
/// `len` bytes from `offset` hold them all.
#[derive(Clone, Copy, Debug)]
struct Span {
    buffer: usize,
    offset: u64,
    len: u64,
    stride: u64,
}

#[derive(Clone, Copy, Debug)]
struct SparseSpans {
    count: u64,
    index_comp: Comp,
    indices: Span,
    values: Span,
}

/// An accessor whose type suits its role and whose ranges lie within the declared lengths
/// of its views and buffers.
#[derive(Clone, Copy, Debug)]
pub(super) struct Accessor {
    count: u64,
    comp: Comp,
    ncomp: usize,
    normalized: bool,
    dense: Option<Span>,
    sparse: Option<SparseSpans>,
}

/// Whether a buffer view may have a `byteStride`: only vertex attributes may.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Packing {
    Strided,
    Tight,
}

impl Accessor {
    /// Checks accessor `index` for `role`; the error says what is wrong, the caller says
    /// where.
    pub(super) fn check(
        root: &json::Root,
        index: usize,
        role: Role,
        rules: Rules,
    ) -> Result<Accessor, String> {
        let a = root
            .accessors
            .get(index)
            .ok_or_else(|| format!("accessor {index} does not exist"))?;
        let (Checked::Valid(comp), Checked::Valid(ty)) = (&a.component_type, &a.type_) else {
            return Err(format!(
                "accessor {index} has an invalid componentType or type"
            ));
        };
        let comp = Comp::of(comp.0);
        let ty = *ty;
        check_role(role, comp, ty, a.normalized, rules.quantization)
            .map_err(|why| format!("accessor {index}: {why}"))?;
        let count = a.count.0;
        if count == 0 {
            return Err(format!("accessor {index} has count 0"));
        }
        let ncomp = components(ty);
        let elem = comp.size() * ncomp as u64;
        let packing = if role == Role::Indices {
            Packing::Tight
        } else {
            Packing::Strided
        };
        let dense = match a.buffer_view {
            Some(v) => Some(
                span(
                    root,
                    v.value(),
                    a.byte_offset.map_or(0, |o| o.0),
                    count,
                    elem,
                    packing,
                )
                .map_err(|why| format!("accessor {index}: {why}"))?,
            ),
            None => {
                if count.saturating_mul(elem) > rules.max_bytes {
                    return Err(format!(
                        "accessor {index} has no buffer view and count {count}: {} bytes of \
                         zeros, over the limit of {} bytes",
                        count.saturating_mul(elem),
                        rules.max_bytes
                    ));
                }
                None
            }
        };
        let sparse = match &a.sparse {
            Some(s) => Some(
                sparse_spans(root, s, count, elem)
                    .map_err(|why| format!("accessor {index} sparse: {why}"))?,
            ),
            None => None,
        };
        Ok(Accessor {
            count,
            comp,
            ncomp,
            normalized: a.normalized,
            dense,
            sparse,
        })
    }

    pub(super) fn count(&self) -> u64 {
        self.count
    }

    pub(super) fn components(&self) -> usize {
        self.ncomp
    }

    /// The buffers this accessor reads.
    pub(super) fn buffers(&self) -> impl Iterator<Item = usize> {
        let sparse = self.sparse.map(|s| [s.indices.buffer, s.values.buffer]);
        self.dense
            .map(|d| d.buffer)
            .into_iter()
            .chain(sparse.into_iter().flatten())
    }

    /// A reader over the loaded buffers. Checks the sparse indices: strictly increasing and
    /// below `count`, as the specification requires and the lookup relies on.
    pub(super) fn reader<'a>(&self, buffers: &'a Buffers) -> Result<Reader<'a>, String> {
        let slice = |s: Span| -> Result<&'a [u8], String> {
            let bytes = buffers
                .get(s.buffer)
                .ok_or_else(|| format!("buffer {} is not loaded", s.buffer))?;
            let start = usize::try_from(s.offset).map_err(|e| e.to_string())?;
            let len = usize::try_from(s.len).map_err(|e| e.to_string())?;
            start
                .checked_add(len)
                .and_then(|end| bytes.get(start..end))
                .ok_or_else(|| format!("buffer {} is shorter than declared", s.buffer))
        };
        let to_usize = |v: u64| usize::try_from(v).map_err(|e| e.to_string());
        let dense = match self.dense {
            Some(d) => Some(Strided {
                bytes: slice(d)?,
                stride: to_usize(d.stride)?,
            }),
            None => None,
        };
        let count = to_usize(self.count)?;
        let sparse = match self.sparse {
            Some(s) => {
                let sparse = SparseReader {
                    indices: slice(s.indices)?,
                    index_size: to_usize(s.index_comp.size())?,
                    index_comp: s.index_comp,
                    count: to_usize(s.count)?,
                    values: slice(s.values)?,
                    value_size: to_usize(s.values.stride)?,
                };
                sparse.check(count)?;
                Some(sparse)
            }
            None => None,
        };
        Ok(Reader {
            count,
            comp: self.comp,
            ncomp: self.ncomp,
            normalized: self.normalized,
            elem_size: to_usize(self.comp.size())?,
            dense,
            sparse,
        })
    }
}

fn check_role(
    role: Role,
    comp: Comp,
    ty: Type,
    normalized: bool,
    quantization: bool,
) -> Result<(), String> {
    use Comp::*;
    let ok = match role {
        Role::Position => {
            ty == Type::Vec3
                && match comp {
                    F32 => !normalized,
                    I8 | U8 | I16 | U16 => quantization,
                    U32 => false,
                }
        }
        Role::Normal => {
            ty == Type::Vec3
                && match comp {
                    F32 => !normalized,
                    I8 | I16 => quantization && normalized,
                    U8 | U16 | U32 => false,
                }
        }
        Role::Colour => {
            matches!(ty, Type::Vec3 | Type::Vec4)
                && match comp {
                    F32 => !normalized,
                    U8 | U16 => normalized,
                    I8 | I16 | U32 => false,
                }
        }
        Role::Indices => ty == Type::Scalar && matches!(comp, U8 | U16 | U32) && !normalized,
    };
    if ok {
        return Ok(());
    }
    let hint = if role == Role::Position && comp != F32 && comp != U32 && !quantization {
        " (integer positions need the KHR_mesh_quantization extension)"
    } else {
        ""
    };
    let norm = if normalized { "normalized " } else { "" };
    Err(format!(
        "{norm}{comp:?} {ty:?} is not a valid type for {role:?}{hint}"
    ))
}

/// The bytes `count` elements of `elem` bytes occupy in buffer view `view`, from `offset`.
fn span(
    root: &json::Root,
    view: usize,
    offset: u64,
    count: u64,
    elem: u64,
    packing: Packing,
) -> Result<Span, String> {
    let v = root
        .buffer_views
        .get(view)
        .ok_or_else(|| format!("buffer view {view} does not exist"))?;
    let buffer = v.buffer.value();
    let b = root
        .buffers
        .get(buffer)
        .ok_or_else(|| format!("buffer view {view} names buffer {buffer}, which does not exist"))?;
    let view_offset = v.byte_offset.map_or(0, |o| o.0);
    let view_len = v.byte_length.0;
    if view_offset
        .checked_add(view_len)
        .is_none_or(|end| end > b.byte_length.0)
    {
        return Err(format!(
            "buffer view {view} (byteOffset {view_offset}, byteLength {view_len}) lies outside \
             buffer {buffer} ({} bytes)",
            b.byte_length.0
        ));
    }
    let stride = match (v.byte_stride, packing) {
        (None, _) => elem,
        (Some(_), Packing::Tight) => {
            return Err(format!(
                "buffer view {view} has a byteStride, which only vertex attributes may have"
            ))
        }
        (Some(s), Packing::Strided) => {
            let s = s.0 as u64;
            if s < elem || s % 4 != 0 || !(4..=252).contains(&s) {
                return Err(format!(
                    "buffer view {view} has byteStride {s}; elements of {elem} bytes need a \
                     multiple of 4 from {} to 252",
                    elem.max(4)
                ));
            }
            s
        }
    };
    let need = (count - 1)
        .checked_mul(stride)
        .and_then(|n| n.checked_add(elem))
        .and_then(|n| n.checked_add(offset));
    match need {
        Some(need) if need <= view_len => Ok(Span {
            buffer,
            offset: view_offset + offset,
            len: need - offset,
            stride,
        }),
        _ => Err(format!(
            "{count} elements of {elem} bytes, {stride} apart, from byteOffset {offset} do not \
             fit buffer view {view} ({view_len} bytes)"
        )),
    }
}

fn sparse_spans(
    root: &json::Root,
    s: &json::accessor::sparse::Sparse,
    count: u64,
    elem: u64,
) -> Result<SparseSpans, String> {
    let n = s.count.0;
    if n == 0 || n > count {
        return Err(format!(
            "count {n} (must be from 1 to the accessor's count {count})"
        ));
    }
    let Checked::Valid(index_comp) = &s.indices.component_type else {
        return Err("invalid indices componentType".into());
    };
    let index_comp = Comp::of(index_comp.0);
    if !matches!(index_comp, Comp::U8 | Comp::U16 | Comp::U32) {
        return Err(format!(
            "indices componentType {index_comp:?} is not unsigned"
        ));
    }
    let indices = span(
        root,
        s.indices.buffer_view.value(),
        s.indices.byte_offset.0,
        n,
        index_comp.size(),
        Packing::Tight,
    )
    .map_err(|why| format!("indices: {why}"))?;
    let values = span(
        root,
        s.values.buffer_view.value(),
        s.values.byte_offset.0,
        n,
        elem,
        Packing::Tight,
    )
    .map_err(|why| format!("values: {why}"))?;
    Ok(SparseSpans {
        count: n,
        index_comp,
        indices,
        values,
    })
}

struct Strided<'a> {
    bytes: &'a [u8],
    stride: usize,
}

struct SparseReader<'a> {
    indices: &'a [u8],
    index_comp: Comp,
    index_size: usize,
    count: usize,
    values: &'a [u8],
    value_size: usize,
}

impl SparseReader<'_> {
    fn index(&self, k: usize) -> Option<u64> {
        let at = k.checked_mul(self.index_size)?;
        Some(component(self.indices, at, self.index_comp, false)? as u64)
    }

    fn check(&self, count: usize) -> Result<(), String> {
        let mut previous: Option<u64> = None;
        for k in 0..self.count {
            let i = self
                .index(k)
                .ok_or_else(|| format!("sparse index {k} cannot be read"))?;
            if i >= count as u64 {
                return Err(format!(
                    "sparse index {k} is {i}, beyond the accessor's count {count}"
                ));
            }
            if previous.is_some_and(|p| i <= p) {
                return Err(format!(
                    "sparse index {k} is {i}: sparse indices must strictly increase"
                ));
            }
            previous = Some(i);
        }
        Ok(())
    }

    /// The position among the sparse values of element `i`, if it is replaced.
    fn find(&self, i: usize) -> Option<usize> {
        let (mut lo, mut hi) = (0, self.count);
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            let v = self.index(mid)?;
            match v.cmp(&(i as u64)) {
                std::cmp::Ordering::Equal => return Some(mid),
                std::cmp::Ordering::Less => lo = mid + 1,
                std::cmp::Ordering::Greater => hi = mid,
            }
        }
        None
    }
}

/// Reads the elements of a checked accessor.
pub(super) struct Reader<'a> {
    count: usize,
    comp: Comp,
    ncomp: usize,
    normalized: bool,
    elem_size: usize,
    dense: Option<Strided<'a>>,
    sparse: Option<SparseReader<'a>>,
}

impl Reader<'_> {
    pub(super) fn count(&self) -> usize {
        self.count
    }

    /// Element `i` with normalized integers mapped to [0, 1] or [-1, 1] (glTF 2.0 §3.11);
    /// components past the type's are 0. `None` when `i` is out of range.
    pub(super) fn get(&self, i: usize) -> Option<[f64; 4]> {
        if i >= self.count {
            return None;
        }
        let replaced = self.sparse.as_ref().and_then(|s| Some((s, s.find(i)?)));
        let (bytes, start) = match (replaced, &self.dense) {
            (Some((s, k)), _) => (s.values, k.checked_mul(s.value_size)?),
            (None, Some(d)) => (d.bytes, i.checked_mul(d.stride)?),
            (None, None) => return Some([0.0; 4]),
        };
        let mut out = [0.0; 4];
        for (k, v) in out.iter_mut().enumerate().take(self.ncomp) {
            let at = start.checked_add(k * self.elem_size)?;
            *v = component(bytes, at, self.comp, self.normalized)?;
        }
        Some(out)
    }

    /// Element `i` of an integer scalar accessor (indices).
    pub(super) fn index(&self, i: usize) -> Option<u32> {
        Some(self.get(i)?[0] as u32)
    }
}

fn component(bytes: &[u8], at: usize, comp: Comp, normalized: bool) -> Option<f64> {
    fn take<const N: usize>(bytes: &[u8], at: usize) -> Option<[u8; N]> {
        bytes.get(at..at.checked_add(N)?)?.try_into().ok()
    }
    Some(match comp {
        Comp::I8 => {
            let v = f64::from(i8::from_le_bytes(take(bytes, at)?));
            if normalized {
                (v / 127.0).max(-1.0)
            } else {
                v
            }
        }
        Comp::U8 => {
            let v = f64::from(u8::from_le_bytes(take(bytes, at)?));
            if normalized {
                v / 255.0
            } else {
                v
            }
        }
        Comp::I16 => {
            let v = f64::from(i16::from_le_bytes(take(bytes, at)?));
            if normalized {
                (v / 32767.0).max(-1.0)
            } else {
                v
            }
        }
        Comp::U16 => {
            let v = f64::from(u16::from_le_bytes(take(bytes, at)?));
            if normalized {
                v / 65535.0
            } else {
                v
            }
        }
        Comp::U32 => f64::from(u32::from_le_bytes(take(bytes, at)?)),
        Comp::F32 => f64::from(f32::from_le_bytes(take(bytes, at)?)),
    })
}
