//! Accessor decoding (glTF 2.0 §3.6 "Buffers, buffer views and accessors"), done here
//! instead of with the crate's reader so that every read is bounds-checked and nothing can
//! panic: `byteOffset`, `byteStride`, `count`, `componentType`, `normalized`, accessors
//! without a buffer view (all zeros) and sparse substitution (§3.6.2.3).

use super::json;
use super::source::{Buffers, view};
use serde_json::Value;

/// Largest element count accepted for an accessor without a buffer view (whose data would
/// be allocated from nothing but the `count` field).
const MAX_VIRTUAL_COUNT: u64 = 1 << 24;

/// A decoded accessor: `count` elements of `ncomp` components each, flat.
pub(super) struct Accessor {
    /// Components per element (1 for SCALAR, 3 for VEC3, …).
    pub ncomp: usize,
    /// Component values, normalised per §3.6.2.4 when the accessor says `normalized`.
    pub values: Vec<f64>,
}

impl Accessor {
    /// Number of elements.
    pub fn count(&self) -> usize {
        self.values.len() / self.ncomp.max(1)
    }

    /// Element `i` as a slice of `ncomp` values.
    pub fn element(&self, i: usize) -> &[f64] {
        &self.values[i * self.ncomp..(i + 1) * self.ncomp]
    }
}

fn component_size(ctype: u64) -> Option<usize> {
    match ctype {
        5120 | 5121 => Some(1),
        5122 | 5123 => Some(2),
        5125 | 5126 => Some(4),
        _ => None,
    }
}

fn type_components(t: &str) -> Option<usize> {
    match t {
        "SCALAR" => Some(1),
        "VEC2" => Some(2),
        "VEC3" => Some(3),
        "VEC4" => Some(4),
        "MAT2" => Some(4),
        "MAT3" => Some(9),
        "MAT4" => Some(16),
        _ => None,
    }
}

/// One component at the start of `b` (which holds at least its size).
fn component(b: &[u8], ctype: u64, normalized: bool) -> f64 {
    // §3.6.2.4: normalised signed values are max(c / (2^(n-1) - 1), -1), unsigned c / (2^n - 1).
    match ctype {
        5120 => {
            let c = b[0] as i8 as f64;
            if normalized { (c / 127.0).max(-1.0) } else { c }
        }
        5121 => {
            let c = b[0] as f64;
            if normalized { c / 255.0 } else { c }
        }
        5122 => {
            let c = i16::from_le_bytes([b[0], b[1]]) as f64;
            if normalized {
                (c / 32767.0).max(-1.0)
            } else {
                c
            }
        }
        5123 => {
            let c = u16::from_le_bytes([b[0], b[1]]) as f64;
            if normalized { c / 65535.0 } else { c }
        }
        5125 => {
            let c = u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64;
            if normalized { c / 4294967295.0 } else { c }
        }
        _ => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
    }
}

/// Reads `count` tightly packed or strided elements from `bytes` starting at `offset`.
#[allow(clippy::too_many_arguments)]
fn read_elements(
    bytes: &[u8],
    offset: u64,
    stride: Option<usize>,
    count: u64,
    ncomp: usize,
    ctype: u64,
    csize: usize,
    normalized: bool,
    out: &mut Vec<f64>,
) -> Result<(), String> {
    let elem = (ncomp * csize) as u64;
    let stride = match stride {
        Some(s) if (s as u64) < elem => {
            return Err(format!(
                "byteStride {s} is smaller than an element ({elem} bytes)"
            ));
        }
        Some(s) => s as u64,
        None => elem,
    };
    if count == 0 {
        return Ok(());
    }
    let last = (count - 1)
        .checked_mul(stride)
        .and_then(|x| x.checked_add(offset))
        .and_then(|x| x.checked_add(elem))
        .filter(|&end| end <= bytes.len() as u64)
        .ok_or_else(|| {
            format!(
                "{count} elements of {elem} bytes (stride {stride}) from byte {offset} do not fit in its buffer view ({} bytes)",
                bytes.len()
            )
        })?;
    debug_assert!(last as usize <= bytes.len());
    out.reserve(count as usize * ncomp);
    let (offset, stride) = (offset as usize, stride as usize);
    for e in 0..count as usize {
        let start = offset + e * stride;
        for c in 0..ncomp {
            out.push(component(&bytes[start + c * csize..], ctype, normalized));
        }
    }
    Ok(())
}

/// Decodes `accessors[i]`, whose `type` must be one of `types`. Integer component types
/// are accepted (KHR_mesh_quantization); the caller checks integrality where it matters.
pub(super) fn read(
    root: &Value,
    buffers: &Buffers<'_>,
    i: usize,
    types: &[&str],
) -> Result<Accessor, String> {
    let at = format!("accessors[{i}]");
    let err = |e: String| format!("{at}: {e}");
    let def = json::array(root, "accessors")?
        .get(i)
        .ok_or_else(|| format!("{at} does not exist"))?;
    let ctype = json::uint(def, "componentType")
        .map_err(err)?
        .ok_or_else(|| err("no `componentType`".into()))?;
    let csize =
        component_size(ctype).ok_or_else(|| err(format!("unknown componentType {ctype}")))?;
    let ty = json::string(def, "type").map_err(err)?.unwrap_or("");
    if !types.contains(&ty) {
        return Err(err(format!(
            "type is '{ty}', expected {}",
            types.join(" or ")
        )));
    }
    let ncomp = type_components(ty).ok_or_else(|| err(format!("unknown type '{ty}'")))?;
    let count = json::uint(def, "count")
        .map_err(err)?
        .ok_or_else(|| err("no `count`".into()))?;
    let normalized = json::boolean(def, "normalized")
        .map_err(err)?
        .unwrap_or(false);
    if normalized && ctype == 5126 {
        return Err(err("FLOAT components cannot be normalized".into()));
    }
    let offset = json::uint(def, "byteOffset").map_err(err)?.unwrap_or(0);

    let mut values = Vec::new();
    match json::index(def, "bufferView").map_err(err)? {
        Some(v) => {
            let view = view(root, buffers, v).map_err(err)?;
            read_elements(
                view.bytes,
                offset,
                view.stride,
                count,
                ncomp,
                ctype,
                csize,
                normalized,
                &mut values,
            )
            .map_err(err)?;
        }
        None => {
            // §3.6.2.3: without a buffer view the accessor is all zeros (then sparse).
            if count > MAX_VIRTUAL_COUNT {
                return Err(err(format!(
                    "count {count} is too large for an accessor without bufferView"
                )));
            }
            values = vec![0.0; count as usize * ncomp];
        }
    }
    if let Some(sparse) = def.get("sparse") {
        apply_sparse(
            root,
            buffers,
            sparse,
            count,
            ncomp,
            ctype,
            csize,
            normalized,
            &mut values,
        )
        .map_err(|e| err(format!("sparse: {e}")))?;
    }
    Ok(Accessor { ncomp, values })
}

/// Substitutes the sparse values into `values` (§3.6.2.3).
#[allow(clippy::too_many_arguments)]
fn apply_sparse(
    root: &Value,
    buffers: &Buffers<'_>,
    sparse: &Value,
    count: u64,
    ncomp: usize,
    ctype: u64,
    csize: usize,
    normalized: bool,
    values: &mut [f64],
) -> Result<(), String> {
    let n = json::uint(sparse, "count")?.ok_or("no `count`")?;
    if n > count {
        return Err(format!("count {n} exceeds the accessor's count {count}"));
    }
    let idx = sparse.get("indices").ok_or("no `indices`")?;
    let val = sparse.get("values").ok_or("no `values`")?;
    let ictype = json::uint(idx, "componentType")?.ok_or("indices: no `componentType`")?;
    if !matches!(ictype, 5121 | 5123 | 5125) {
        return Err(format!(
            "indices: componentType {ictype} is not an unsigned integer type"
        ));
    }
    let isize = component_size(ictype).unwrap_or(4);
    let iview = view(
        root,
        buffers,
        json::index(idx, "bufferView")?.ok_or("indices: no `bufferView`")?,
    )?;
    let vview = view(
        root,
        buffers,
        json::index(val, "bufferView")?.ok_or("values: no `bufferView`")?,
    )?;
    let mut indices = Vec::new();
    let ioff = json::uint(idx, "byteOffset")?.unwrap_or(0);
    read_elements(
        iview.bytes,
        ioff,
        None,
        n,
        1,
        ictype,
        isize,
        false,
        &mut indices,
    )
    .map_err(|e| format!("indices: {e}"))?;
    let mut subst = Vec::new();
    let voff = json::uint(val, "byteOffset")?.unwrap_or(0);
    read_elements(
        vview.bytes,
        voff,
        None,
        n,
        ncomp,
        ctype,
        csize,
        normalized,
        &mut subst,
    )
    .map_err(|e| format!("values: {e}"))?;
    for (k, &target) in indices.iter().enumerate() {
        if target >= count as f64 {
            return Err(format!("index {target} is out of range (count {count})"));
        }
        let t = target as usize;
        values[t * ncomp..(t + 1) * ncomp].copy_from_slice(&subst[k * ncomp..(k + 1) * ncomp]);
    }
    Ok(())
}

/// Decodes an index accessor (`SCALAR` of UNSIGNED_BYTE / SHORT / INT, §3.7.2.1).
pub(super) fn read_indices(
    root: &Value,
    buffers: &Buffers<'_>,
    i: usize,
) -> Result<Vec<u32>, String> {
    let def = json::array(root, "accessors")?
        .get(i)
        .ok_or_else(|| format!("accessors[{i}] does not exist"))?;
    let ctype = json::uint(def, "componentType").ok().flatten().unwrap_or(0);
    if !matches!(ctype, 5121 | 5123 | 5125)
        || json::boolean(def, "normalized").ok().flatten() == Some(true)
    {
        return Err(format!(
            "accessors[{i}]: indices must be UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT, not componentType {ctype}"
        ));
    }
    let a = read(root, buffers, i, &["SCALAR"])?;
    Ok(a.values.iter().map(|&v| v as u32).collect())
}
