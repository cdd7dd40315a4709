//! Bytes in: the GLB container, URIs (data URIs, relative paths kept inside the scene's
//! folder), buffers and buffer views.

use super::json;
use base64::Engine as _;
use serde_json::Value;
use std::cell::OnceCell;
use std::path::{Path, PathBuf};

/// GLB chunk type of the JSON chunk ("JSON", little-endian).
const CHUNK_JSON: u32 = 0x4E4F_534A;
/// GLB chunk type of the binary chunk ("BIN\0", little-endian).
const CHUNK_BIN: u32 = 0x004E_4942;

/// The two parts of a glTF file: its JSON text and, for GLB, the BIN chunk.
pub(super) struct Container<'a> {
    pub json: &'a [u8],
    pub bin: Option<&'a [u8]>,
    /// Recovered problems in the container (duplicate chunks, a byte-order mark).
    pub notes: Vec<String>,
}

fn le_u32(b: &[u8], at: usize) -> Option<u32> {
    let s = b.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
}

/// Splits a file into JSON and BIN: a GLB (by its `glTF` magic, whatever the extension)
/// per glTF 2.0 §4.4 "GLB File Format Specification", else the whole file as JSON.
pub(super) fn split(bytes: &[u8]) -> Result<Container<'_>, String> {
    let mut notes = Vec::new();
    if !bytes.starts_with(b"glTF") {
        let mut json = bytes;
        if let Some(rest) = json.strip_prefix(b"\xEF\xBB\xBF".as_slice()) {
            notes.push(
                "the JSON starts with a UTF-8 byte-order mark (not allowed by the spec); ignored"
                    .into(),
            );
            json = rest;
        }
        return Ok(Container {
            json,
            bin: None,
            notes,
        });
    }
    let version = le_u32(bytes, 4).ok_or("GLB header is truncated")?;
    if version != 2 {
        return Err(format!(
            "GLB container version {version} is not supported (only glTF 2.0)"
        ));
    }
    let length = le_u32(bytes, 8).ok_or("GLB header is truncated")? as usize;
    if length > bytes.len() {
        return Err(format!(
            "GLB header says the file has {length} bytes but it has {} (truncated?)",
            bytes.len()
        ));
    }
    if length < 12 {
        return Err(format!(
            "GLB header gives an impossible length of {length} bytes"
        ));
    }
    let body = &bytes[..length];
    let mut at = 12usize;
    let mut json: Option<&[u8]> = None;
    let mut bin: Option<&[u8]> = None;
    let mut index = 0;
    while at < body.len() {
        let (Some(len), Some(kind)) = (le_u32(body, at), le_u32(body, at + 4)) else {
            return Err(format!("GLB chunk {index} header is truncated"));
        };
        let start = at + 8;
        let end = start
            .checked_add(len as usize)
            .filter(|&e| e <= body.len())
            .ok_or_else(|| {
                format!("GLB chunk {index} ({len} bytes) runs past the end of the file")
            })?;
        let data = &body[start..end];
        match kind {
            CHUNK_JSON if index == 0 => json = Some(data),
            CHUNK_JSON => notes.push(format!("GLB chunk {index}: extra JSON chunk ignored")),
            _ if index == 0 => return Err("GLB: the first chunk is not the JSON chunk".into()),
            CHUNK_BIN if bin.is_none() => bin = Some(data),
            CHUNK_BIN => notes.push(format!("GLB chunk {index}: extra BIN chunk ignored")),
            _ => {} // unknown chunk types must be ignored (spec §4.4.3.1)
        }
        at = end;
        index += 1;
    }
    let json = json.ok_or("GLB file has no JSON chunk")?;
    // The JSON chunk is padded with spaces; tolerate NUL padding too.
    let trimmed = json.len() - json.iter().rev().take_while(|&&c| c == 0).count();
    let mut json = &json[..trimmed];
    if let Some(rest) = json.strip_prefix(b"\xEF\xBB\xBF".as_slice()) {
        notes.push(
            "the JSON chunk starts with a UTF-8 byte-order mark (not allowed by the spec); ignored"
                .into(),
        );
        json = rest;
    }
    Ok(Container { json, bin, notes })
}

/// Decodes `%XX` escapes of a URI into bytes (RFC 3986 §2.1); other bytes pass through.
fn percent_decode(s: &str) -> Vec<u8> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() {
            let hex = |c: u8| (c as char).to_digit(16);
            if let (Some(h), Some(l)) = (hex(b[i + 1]), hex(b[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    out
}

/// Where a URI leads.
pub(super) enum Target {
    /// A `data:` URI, already decoded.
    Data(Vec<u8>),
    /// A file inside the scene's folder.
    File(PathBuf),
}

/// Resolves a glTF URI relative to the scene's folder `dir`. Only `data:` URIs and relative
/// paths that stay inside `dir` (after decoding `%XX` and resolving `.` and `..`
/// lexically) are allowed; absolute paths, other schemes and paths escaping the folder are
/// refused, so a scene file cannot make the loader read arbitrary files.
pub(super) fn resolve_uri(dir: &Path, uri: &str) -> Result<Target, String> {
    if uri.len() >= 5 && uri[..5].eq_ignore_ascii_case("data:") {
        let comma = uri.find(',').ok_or("data URI without a comma")?;
        let (header, payload) = (&uri[5..comma], &uri[comma + 1..]);
        if header.to_ascii_lowercase().ends_with(";base64") {
            let engine = base64::engine::GeneralPurpose::new(
                &base64::alphabet::STANDARD,
                base64::engine::GeneralPurposeConfig::new()
                    .with_decode_padding_mode(base64::engine::DecodePaddingMode::Indifferent)
                    .with_decode_allow_trailing_bits(true),
            );
            let clean: String = payload
                .chars()
                .filter(|c| !c.is_ascii_whitespace())
                .collect();
            return engine
                .decode(clean.as_bytes())
                .map(Target::Data)
                .map_err(|e| format!("data URI is not valid base64 ({e})"));
        }
        return Ok(Target::Data(percent_decode(payload)));
    }
    // A scheme is letters followed by ':' before any '/' ("http:", "file:"; "C:" too).
    if let Some(colon) = uri.find(':') {
        let scheme = &uri[..colon];
        if !scheme.is_empty()
            && scheme
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
            && scheme.starts_with(|c: char| c.is_ascii_alphabetic())
        {
            return Err(format!(
                "URI '{uri}' is not a relative path or data URI (only those are allowed)"
            ));
        }
    }
    let decoded = String::from_utf8(percent_decode(uri))
        .map_err(|_| format!("URI '{uri}' does not decode to UTF-8"))?;
    if decoded.starts_with(['/', '\\']) || decoded.contains('\0') {
        return Err(format!(
            "URI '{uri}' is an absolute path (only paths inside the scene's folder are allowed)"
        ));
    }
    let mut parts: Vec<&str> = Vec::new();
    for part in decoded.split(['/', '\\']) {
        match part {
            "" | "." => {}
            ".." => {
                if parts.pop().is_none() {
                    return Err(format!("URI '{uri}' points outside the scene's folder"));
                }
            }
            p => parts.push(p),
        }
    }
    if parts.is_empty() {
        return Err(format!("URI '{uri}' names no file"));
    }
    let mut path = dir.to_path_buf();
    path.extend(parts);
    Ok(Target::File(path))
}

/// The file's buffers, each loaded on first use.
pub(super) struct Buffers<'a> {
    dir: PathBuf,
    defs: &'a [Value],
    bin: Option<Vec<u8>>,
    loaded: Vec<OnceCell<Result<Vec<u8>, String>>>,
    /// Shortfalls found when loading (data shorter than `byteLength`): warnings.
    pub notes: std::cell::RefCell<Vec<String>>,
    /// The first buffer that could not be loaded: fatal for the whole file.
    failed: std::cell::RefCell<Option<String>>,
}

impl<'a> Buffers<'a> {
    /// Buffers defined by `defs` (the `buffers` array) relative to `dir`, with the GLB BIN chunk.
    pub fn new(dir: &Path, defs: &'a [Value], bin: Option<Vec<u8>>) -> Self {
        Buffers {
            dir: dir.to_path_buf(),
            defs,
            bin,
            loaded: (0..defs.len()).map(|_| OnceCell::new()).collect(),
            notes: Default::default(),
            failed: Default::default(),
        }
    }

    /// The error of the first buffer that could not be loaded, if any. A scene with a
    /// missing or unreadable buffer is refused rather than shown with holes.
    pub fn failure(&self) -> Option<String> {
        self.failed.borrow().clone()
    }

    /// The bytes of buffer `i`, loading it the first time. Errors name the buffer and file.
    pub fn get(&self, i: usize) -> Result<&[u8], String> {
        let cell = self
            .loaded
            .get(i)
            .ok_or_else(|| format!("buffer {i} does not exist ({} buffers)", self.defs.len()))?;
        cell.get_or_init(|| {
            let r = self.load(i);
            if let Err(e) = &r {
                self.failed.borrow_mut().get_or_insert_with(|| e.clone());
            }
            r
        })
        .as_deref()
        .map_err(Clone::clone)
    }

    fn load(&self, i: usize) -> Result<Vec<u8>, String> {
        let def = &self.defs[i];
        let at = format!("buffers[{i}]");
        let uri = json::string(def, "uri").map_err(|e| format!("{at}: {e}"))?;
        let data = match uri {
            None if i == 0 => self
                .bin
                .clone()
                .ok_or_else(|| format!("{at} has no uri and the file has no GLB BIN chunk"))?,
            None => return Err(format!("{at} has no uri")),
            Some(uri) => match resolve_uri(&self.dir, uri).map_err(|e| format!("{at}: {e}"))? {
                Target::Data(d) => d,
                Target::File(p) => std::fs::read(&p)
                    .map_err(|e| format!("{at}: cannot read '{}': {e}", p.display()))?,
            },
        };
        if let Ok(Some(len)) = json::uint(def, "byteLength")
            && (data.len() as u64) < len
        {
            self.notes.borrow_mut().push(format!(
                "{at}: has {} bytes but byteLength says {len}; reads past the end will fail",
                data.len()
            ));
        }
        Ok(data)
    }
}

/// A resolved buffer view: its bytes and optional `byteStride`.
pub(super) struct View<'b> {
    pub bytes: &'b [u8],
    pub stride: Option<usize>,
}

/// Resolves `bufferViews[i]` to its bytes (bounds-checked against the buffer).
pub(super) fn view<'b>(
    root: &Value,
    buffers: &'b Buffers<'_>,
    i: usize,
) -> Result<View<'b>, String> {
    let at = format!("bufferViews[{i}]");
    let def = json::array(root, "bufferViews")?
        .get(i)
        .ok_or_else(|| format!("{at} does not exist"))?;
    let err = |e: String| format!("{at}: {e}");
    let buffer = json::index(def, "buffer")
        .map_err(err)?
        .ok_or_else(|| err("no `buffer`".into()))?;
    let offset = json::uint(def, "byteOffset").map_err(err)?.unwrap_or(0);
    let length = json::uint(def, "byteLength")
        .map_err(err)?
        .ok_or_else(|| err("no `byteLength`".into()))?;
    let stride = json::uint(def, "byteStride").map_err(err)?;
    if let Some(s) = stride
        && !(4..=252).contains(&s)
    {
        return Err(err(format!("byteStride {s} is outside 4..=252")));
    }
    let data = buffers.get(buffer)?;
    let end = offset
        .checked_add(length)
        .filter(|&e| e <= data.len() as u64)
        .ok_or_else(|| {
            err(format!(
                "bytes {offset}..+{length} lie outside buffer {buffer} ({} bytes)",
                data.len()
            ))
        })?;
    Ok(View {
        bytes: &data[offset as usize..end as usize],
        stride: stride.map(|s| s as usize),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uris() {
        let dir = Path::new("scenes/a");
        let file = |u: &str| match resolve_uri(dir, u) {
            Ok(Target::File(p)) => Ok(p),
            Ok(Target::Data(_)) => Err("data".to_string()),
            Err(e) => Err(e),
        };
        assert_eq!(
            file("Box%20With%20Spaces.bin").unwrap(),
            dir.join("Box With Spaces.bin")
        );
        assert_eq!(file("x/../y/./z.bin").unwrap(), dir.join("y").join("z.bin"));
        assert!(file("../b.bin").is_err());
        assert!(file("x/../../b.bin").is_err());
        assert!(file("%2e%2e/b.bin").is_err());
        assert!(file("/etc/passwd").is_err());
        assert!(file("..\\..\\etc\\passwd").is_err());
        assert!(file("http://example.com/a.bin").is_err());
        assert!(file("file:///etc/passwd").is_err());
        match resolve_uri(dir, "data:application/octet-stream;base64,AAEC") {
            Ok(Target::Data(d)) => assert_eq!(d, vec![0, 1, 2]),
            _ => panic!("data URI"),
        }
    }

    #[test]
    fn percent() {
        assert_eq!(percent_decode("a%20b%e2%9d%a4"), "a b❤".as_bytes());
        assert_eq!(percent_decode("100%"), b"100%");
        assert_eq!(percent_decode("%4"), b"%4");
    }
}
