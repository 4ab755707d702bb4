//! The seeded mutation harness: every reader is fed damaged copies of the project's own valid
//! files (the sample cases, and files the project writes), and each copy must end in success
//! or a typed error: no panic, no abort, no signal, within an address-space limit.
//!
//! Each *target* is one reader and one valid file. Its inputs are that file under seeded
//! mutations ([`Edit`]): byte flips, truncation, insertion and deletion, integers written over
//! bytes, and structured edits that know the format (a DICOM element's value or length, the
//! transfer syntax UID, a NIfTI header field, a number or a word of a text format such as a
//! count or a type). Input `n` of a target is mutated by the generator seeded with `n`, so a
//! failure names the target, the seed and the edits, and
//! `OTOATLAS_REPLAY=target:seed cargo test --test pipeline robustness -- --include-ignored
//! --nocapture` runs that input alone and keeps it on disk.
//!
//! Readers the command line reaches in a few milliseconds (DICOM and NIfTI through `inspect`,
//! the configuration through `--config`, the atlas through `atlas info --atlas`, the package
//! manifest through `verify`) run as the `otoatlas` binary, one process per input, under
//! `prlimit --as`: the exit code must be 0 or 2 (`verify` may say 1, a fault it found) and
//! a failure must be one line `error: ...` without Rust debug text. The landmark and mesh
//! readers, which the command line reaches only after other work, run in a child copy of this
//! test binary ([`library_readers_child`]) under the same limit, many inputs per child; each
//! error must be one line without debug text.

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::common;

/// Address space each child may map: far above what reading these small files needs, far
/// below what a header-sized allocation (up to 4 GiB per DICOM element) would take.
const ADDRESS_SPACE_BYTES: u64 = 1 << 30;

/// Environment variable naming one `target:seed` to run alone (and keep).
const REPLAY: &str = "OTOATLAS_REPLAY";
/// Environment variable scaling every target's number of inputs (default 1).
const SCALE: &str = "OTOATLAS_HARNESS_SCALE";
/// Environment variable handing the child its job file.
const CHILD_JOBS: &str = "OTOATLAS_HARNESS_JOBS";

/// One change to a file's bytes.
#[derive(Debug, Clone)]
enum Edit {
    /// `byte ^= mask`.
    Flip {
        at: usize,
        mask: u8,
    },
    Truncate {
        len: usize,
    },
    Insert {
        at: usize,
        bytes: Vec<u8>,
    },
    Delete {
        at: usize,
        len: usize,
    },
    /// An integer written over `width` bytes.
    Int {
        at: usize,
        width: usize,
        big_endian: bool,
        value: u64,
    },
    /// A DICOM element's value replaced (its length field follows).
    DicomValue {
        tag: (u16, u16),
        value: Vec<u8>,
    },
    /// A DICOM element's length field set, the value left as it is.
    DicomLength {
        tag: (u16, u16),
        length: u32,
    },
    /// A NIfTI-1 header field set.
    NiftiField {
        #[expect(dead_code, reason = "named in a failure's report (Debug)")]
        field: &'static str,
        at: usize,
        bytes: Vec<u8>,
    },
    /// A token (number or word) of a text format replaced.
    Token {
        at: usize,
        len: usize,
        with: String,
    },
}

/// What the structured edits know about a target's format.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Format {
    Dicom,
    /// Uncompressed NIfTI-1 (a `.nii.gz` target gzips the edited bytes).
    Nifti,
    Text,
    Binary,
}

/// How an input reaches its reader.
#[derive(Debug, Clone, Copy)]
enum Reader {
    /// The `otoatlas` binary with these arguments; `{}` stands for the input's path (or the
    /// folder holding it, see [`Target::folder`]). `faults_exit_1`: exit 1 is an answer too.
    Cli {
        args: &'static [&'static str],
        faults_exit_1: bool,
    },
    /// A library reader in the child, by name (see [`read_with`]).
    Library(&'static str),
}

/// One reader and one valid file it reads.
struct Target {
    name: &'static str,
    /// The valid file's bytes.
    base: Vec<u8>,
    format: Format,
    /// The file name the input is written under (its extension picks the reader).
    file: &'static str,
    /// Files the input sits beside in its folder (the atlas's other file, a package's).
    folder: Option<PathBuf>,
    /// Gzip the mutated bytes (a `.nii.gz` whose content is damaged).
    gzip: bool,
    reader: Reader,
    inputs: usize,
}

/// Deterministic seed of input `n` of `target`.
fn seed_of(target: &str, n: usize) -> u64 {
    target
        .bytes()
        .fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
            (h ^ b as u64).wrapping_mul(0x100_0000_01b3)
        })
        .wrapping_add(n as u64)
}

const INTERESTING: [u64; 14] = [
    0,
    1,
    2,
    0x7f,
    0xff,
    0x7fff,
    0x8000,
    0xffff,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_fffe,
    0xffff_ffff,
    0x3b9a_ca00, // 1e9
    u64::MAX,
];

const INTERESTING_TEXT: [&str; 16] = [
    "0",
    "-1",
    "1",
    "4294967295",
    "4294967296",
    "18446744073709551615",
    "9999999999999999999999",
    "1e308",
    "-1e308",
    "nan",
    "NaN",
    "inf",
    "",
    "x",
    "0.0000001",
    "\"",
];

/// Words a text edit may put in place of another: types, keywords and units of the formats.
const WORDS: [&str; 20] = [
    "float", "double", "uchar", "int", "list", "Float32", "Float64", "Int64", "UInt8", "binary",
    "ascii", "appended", "LPS", "RAS", "m", "mm", "true", "null", "[]", "{}",
];

/// (tag, offset of the length field, its width, offset of the value, value length).
type DicomElement = ((u16, u16), usize, usize, usize, usize);

/// The explicit-VR little-endian elements of a DICOM file the project wrote.
fn dicom_elements(bytes: &[u8]) -> Vec<DicomElement> {
    let mut out = Vec::new();
    let mut at = 132;
    let u16_at = |i: usize| u16::from_le_bytes([bytes[i], bytes[i + 1]]);
    while at + 8 <= bytes.len() {
        let tag = (u16_at(at), u16_at(at + 2));
        let vr = &bytes[at + 4..at + 6];
        let long = matches!(
            vr,
            b"OB" | b"OW" | b"OF" | b"SQ" | b"UT" | b"UN" | b"OD" | b"OL" | b"OV" | b"UC" | b"UR"
        );
        let (len_at, width, value_at) = if long {
            (at + 8, 4, at + 12)
        } else {
            (at + 6, 2, at + 8)
        };
        if value_at > bytes.len() {
            break;
        }
        let len = if long {
            u32::from_le_bytes(bytes[len_at..len_at + 4].try_into().unwrap()) as usize
        } else {
            u16_at(len_at) as usize
        };
        out.push((tag, len_at, width, value_at, len));
        at = value_at + len;
    }
    out
}

/// A DICOM value for a structured edit of `tag`.
fn dicom_value(tag: (u16, u16), rng: &mut ChaCha8Rng) -> Vec<u8> {
    let pick =
        |rng: &mut ChaCha8Rng, v: &[&str]| v[rng.random_range(0..v.len())].as_bytes().to_vec();
    match tag {
        (0x0002, 0x0010) => pick(
            rng,
            &[
                "1.2.840.10008.1.2.2\0",  // explicit VR big endian: the body says otherwise
                "1.2.840.10008.1.2\0",    // implicit VR little endian
                "1.2.840.10008.1.2.1.99", // deflated
                "1.2.840.10008.1.2.4.50", // JPEG baseline
                "1.2.840.10008.1.2.5\0",  // RLE
                "1.2.3\0",
                "",
            ],
        ),
        (0x0028, 0x0008) => pick(rng, &["1000000000", "10000000", "-1", "0 ", "1e9 ", "x "]),
        (0x0028, _) if rng.random_bool(0.8) => (INTERESTING[rng.random_range(0..INTERESTING.len())]
            as u16)
            .to_le_bytes()
            .to_vec(),
        _ => pick(
            rng,
            &["", "0 ", "-1", "1e308 ", "nan ", "\\\\\\ ", "9999999999"],
        ),
    }
}

/// The NIfTI-1 header fields a structured edit sets: (name, offset, width, is float).
const NIFTI_FIELDS: [(&str, usize, usize, bool); 16] = [
    ("sizeof_hdr", 0, 4, false),
    ("dim[0]", 40, 2, false),
    ("dim[1]", 42, 2, false),
    ("dim[2]", 44, 2, false),
    ("dim[3]", 46, 2, false),
    ("dim[4]", 48, 2, false),
    ("datatype", 70, 2, false),
    ("bitpix", 72, 2, false),
    ("pixdim[0]", 76, 4, true),
    ("pixdim[1]", 80, 4, true),
    ("pixdim[3]", 88, 4, true),
    ("vox_offset", 108, 4, true),
    ("scl_slope", 112, 4, true),
    ("scl_inter", 116, 4, true),
    ("qform_code", 252, 2, false),
    ("quatern_b", 256, 4, true),
];

fn nifti_value(width: usize, float: bool, rng: &mut ChaCha8Rng) -> Vec<u8> {
    if float {
        let v = [
            0.0f32,
            -1.0,
            1e30,
            -1e30,
            f32::NAN,
            f32::INFINITY,
            1e-30,
            352.0,
            3.5e9,
        ];
        return v[rng.random_range(0..v.len())].to_le_bytes().to_vec();
    }
    // datatypes of the standard among the extremes
    let v: [i64; 22] = [
        0, 1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 768, 1024, 1280, 1536, 1792, 2048, 2304, -1,
        32767, -32768, 348,
    ];
    let x = v[rng.random_range(0..v.len())];
    if width == 2 {
        (x as i16).to_le_bytes().to_vec()
    } else {
        (x as i32).to_le_bytes().to_vec()
    }
}

/// Byte spans of the numbers and words of a text.
fn tokens(bytes: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = None;
    for (i, &b) in bytes.iter().enumerate() {
        let part = b.is_ascii_alphanumeric() || b == b'.' || b == b'-' || b == b'+' || b == b'_';
        match (part, start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                out.push((s, i - s));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        out.push((s, bytes.len() - s));
    }
    out
}

/// A position in `0..len`, biased to the first 512 bytes, where headers are.
fn position(len: usize, rng: &mut ChaCha8Rng) -> usize {
    if len == 0 {
        return 0;
    }
    if rng.random_bool(0.5) {
        rng.random_range(0..len.min(512))
    } else {
        rng.random_range(0..len)
    }
}

/// One random edit of `bytes` in `format`.
fn random_edit(bytes: &[u8], format: Format, rng: &mut ChaCha8Rng) -> Edit {
    let len = bytes.len();
    // one in two edits is structured, where the format allows
    if rng.random_bool(0.5) {
        match format {
            Format::Dicom => {
                let elements = dicom_elements(bytes);
                if !elements.is_empty() {
                    let (tag, ..) = elements[rng.random_range(0..elements.len())];
                    let tag = match rng.random_range(0..6) {
                        0 => (0x0002, 0x0010),
                        1 => (0x0028, 0x0008),
                        2 => (0x0028, 0x0010),
                        3 => (0x7fe0, 0x0010),
                        _ => tag,
                    };
                    return if rng.random_bool(0.5) {
                        Edit::DicomValue {
                            tag,
                            value: dicom_value(tag, rng),
                        }
                    } else {
                        Edit::DicomLength {
                            tag,
                            length: INTERESTING[rng.random_range(0..INTERESTING.len())] as u32,
                        }
                    };
                }
            }
            Format::Nifti => {
                let (field, at, width, float) =
                    NIFTI_FIELDS[rng.random_range(0..NIFTI_FIELDS.len())];
                return Edit::NiftiField {
                    field,
                    at,
                    bytes: nifti_value(width, float, rng),
                };
            }
            Format::Text | Format::Binary => {
                let spans = tokens(bytes);
                if format == Format::Text && !spans.is_empty() {
                    // header-heavy: half the picks among the first 64 tokens
                    let k = if rng.random_bool(0.5) {
                        rng.random_range(0..spans.len().min(64))
                    } else {
                        rng.random_range(0..spans.len())
                    };
                    let (at, len) = spans[k];
                    let with = if rng.random_bool(0.6) {
                        INTERESTING_TEXT[rng.random_range(0..INTERESTING_TEXT.len())]
                    } else {
                        WORDS[rng.random_range(0..WORDS.len())]
                    };
                    return Edit::Token {
                        at,
                        len,
                        with: with.to_string(),
                    };
                }
            }
        }
    }
    match rng.random_range(0..5) {
        0 => Edit::Flip {
            at: position(len, rng),
            mask: rng.random_range(1..=255),
        },
        1 => Edit::Truncate {
            len: position(len, rng),
        },
        2 => Edit::Insert {
            at: position(len, rng),
            bytes: (0..rng.random_range(1..16)).map(|_| rng.random()).collect(),
        },
        3 => Edit::Delete {
            at: position(len, rng),
            len: rng.random_range(1..64),
        },
        _ => Edit::Int {
            at: position(len, rng),
            width: [1, 2, 4, 8][rng.random_range(0..4)],
            big_endian: rng.random_bool(0.3),
            value: INTERESTING[rng.random_range(0..INTERESTING.len())],
        },
    }
}

/// `bytes` with `edit` applied (an edit that does not fit leaves them as they are).
fn apply(bytes: &mut Vec<u8>, edit: &Edit) {
    let len = bytes.len();
    match edit {
        Edit::Flip { at, mask } => {
            if let Some(b) = bytes.get_mut(*at) {
                *b ^= mask;
            }
        }
        Edit::Truncate { len } => bytes.truncate(*len),
        Edit::Insert { at, bytes: new } => {
            let at = (*at).min(len);
            bytes.splice(at..at, new.iter().copied());
        }
        Edit::Delete { at, len: n } => {
            let at = (*at).min(len);
            bytes.drain(at..(at + n).min(len));
        }
        Edit::Int {
            at,
            width,
            big_endian,
            value,
        } => {
            let raw = if *big_endian {
                value.to_be_bytes()[8 - width..].to_vec()
            } else {
                value.to_le_bytes()[..*width].to_vec()
            };
            let end = (at + width).min(len);
            if *at < end {
                bytes[*at..end].copy_from_slice(&raw[..end - at]);
            }
        }
        Edit::DicomValue { tag, value } => {
            if let Some(&(_, len_at, width, value_at, old)) =
                dicom_elements(bytes).iter().find(|e| e.0 == *tag)
            {
                let n = value.len() as u32;
                if width == 2 {
                    bytes[len_at..len_at + 2].copy_from_slice(&(n as u16).to_le_bytes());
                } else {
                    bytes[len_at..len_at + 4].copy_from_slice(&n.to_le_bytes());
                }
                let end = (value_at + old).min(bytes.len());
                bytes.splice(value_at..end, value.iter().copied());
            }
        }
        Edit::DicomLength { tag, length } => {
            if let Some(&(_, len_at, width, ..)) =
                dicom_elements(bytes).iter().find(|e| e.0 == *tag)
            {
                if width == 2 {
                    bytes[len_at..len_at + 2].copy_from_slice(&(*length as u16).to_le_bytes());
                } else {
                    bytes[len_at..len_at + 4].copy_from_slice(&length.to_le_bytes());
                }
            }
        }
        Edit::NiftiField { at, bytes: new, .. } => {
            if at + new.len() <= len {
                bytes[*at..at + new.len()].copy_from_slice(new);
            }
        }
        Edit::Token { at, len: n, with } => {
            let end = (at + n).min(len);
            if *at <= end {
                bytes.splice(*at..end, with.bytes());
            }
        }
    }
}

/// Input `seed` of `target`: one to three edits, and the mutated bytes.
fn mutate(target: &Target, seed: u64) -> (Vec<Edit>, Vec<u8>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut bytes = target.base.clone();
    let mut edits = Vec::new();
    for _ in 0..rng.random_range(1..=3) {
        let edit = random_edit(&bytes, target.format, &mut rng);
        apply(&mut bytes, &edit);
        edits.push(edit);
    }
    if target.gzip {
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        gz.write_all(&bytes).unwrap();
        bytes = gz.finish().unwrap();
    }
    (edits, bytes)
}

/// What is wrong with an error message, if anything: it must be one line and carry no Rust
/// debug text nor a size of nothing.
fn message_fault(message: &str) -> Option<&'static str> {
    let message = message.trim_end();
    if message.is_empty() {
        return Some("no message");
    }
    if message.contains('\n') {
        return Some("more than one line");
    }
    for debug in [
        "Some(",
        "None",
        "Error {",
        "kind:",
        "panicked",
        "Os {",
        "0 MiB above",
    ] {
        if message.contains(debug) {
            return Some("Rust debug text");
        }
    }
    // an allocation that failed under the limit was sized by a header before any check
    if message.contains("allocate memory") || message.contains("reserve memory") {
        return Some("an allocation sized by a header");
    }
    None
}

/// A `prlimit` command holding a child to [`ADDRESS_SPACE_BYTES`].
fn limited(program: &Path) -> Command {
    let mut cmd = Command::new("prlimit");
    cmd.arg(format!("--as={ADDRESS_SPACE_BYTES}"))
        .arg("--")
        .arg(program);
    cmd
}

/// The verdict on one CLI run: `None` when it ended as it may.
fn cli_fault(out: &Output, faults_exit_1: bool) -> Option<String> {
    let stderr = String::from_utf8_lossy(&out.stderr);
    match out.status.code() {
        Some(0) => None,
        Some(1) if faults_exit_1 => None,
        Some(2) => {
            let line = stderr.trim_end();
            if !line.starts_with("error: ") {
                return Some(format!("exit 2 without 'error: ...': {line}"));
            }
            message_fault(line).map(|f| format!("{f}: {line}"))
        }
        Some(code) => Some(format!("exit {code}: {}", stderr.trim_end())),
        None => Some(format!("killed by a signal: {}", stderr.trim_end())),
    }
}

/// Where input `seed` of `target` is written: `dir/FILE`, beside copies of the target's folder.
fn place(target: &Target, dir: &Path, bytes: &[u8]) -> PathBuf {
    if let Some(folder) = &target.folder {
        std::fs::create_dir_all(dir).unwrap();
        for entry in std::fs::read_dir(folder).unwrap() {
            let entry = entry.unwrap();
            if entry.file_type().unwrap().is_file() && entry.file_name() != target.file {
                let to = dir.join(entry.file_name());
                if !to.exists() {
                    std::fs::hard_link(entry.path(), &to)
                        .or_else(|_| std::fs::copy(entry.path(), &to).map(drop))
                        .unwrap();
                }
            }
        }
    } else {
        std::fs::create_dir_all(dir).unwrap();
    }
    let path = dir.join(target.file);
    std::fs::write(&path, bytes).unwrap();
    path
}

fn cli_args(args: &[&str], input: &Path, folder: bool) -> Vec<OsString> {
    let path = if folder {
        input.parent().unwrap()
    } else {
        input
    };
    args.iter()
        .map(|a| {
            if *a == "{}" {
                path.as_os_str().to_owned()
            } else {
                OsString::from(a)
            }
        })
        .collect()
}

/// One failed input: what it was and what went wrong.
struct Failure {
    target: &'static str,
    seed: u64,
    edits: Vec<Edit>,
    what: String,
}

/// Runs every input of the CLI `target`, one process each.
fn run_cli_target(target: &Target, work: &Path, only: Option<u64>, failures: &mut Vec<Failure>) {
    let Reader::Cli {
        args,
        faults_exit_1,
    } = target.reader
    else {
        unreachable!()
    };
    let dir = work.join(target.name);
    for n in 0..target.inputs {
        let seed = seed_of(target.name, n);
        if only.is_some_and(|s| s != seed) {
            continue;
        }
        let (edits, bytes) = mutate(target, seed);
        let input = place(target, &dir, &bytes);
        let out = limited(Path::new(env!("CARGO_BIN_EXE_otoatlas")))
            .arg("--quiet")
            .args(cli_args(args, &input, target.folder.is_some()))
            .output()
            .expect("run prlimit otoatlas");
        if only.is_some() {
            eprintln!(
                "{}:{seed}: {edits:?}\ninput kept: {}\nexit {:?}\nstderr: {}",
                target.name,
                input.display(),
                out.status.code(),
                String::from_utf8_lossy(&out.stderr)
            );
        }
        if let Some(what) = cli_fault(&out, faults_exit_1) {
            failures.push(Failure {
                target: target.name,
                seed,
                edits,
                what,
            });
        }
    }
}

/// Reads `path` with the library reader `reader`: `Err` holds the error's message.
fn read_with(reader: &str, path: &Path) -> Result<(), String> {
    use otoatlas::mesh::io::{gmsh, obj, ply, stl, vtu};
    let shown = |e: &dyn std::fmt::Display| e.to_string();
    match reader {
        "landmarks" => otoatlas::ear::read_landmarks(path)
            .map(drop)
            .map_err(|e| shown(&e)),
        "ply" => ply::read_ply(path).map(drop).map_err(|e| shown(&e)),
        "stl" => stl::read_stl(path).map(drop).map_err(|e| shown(&e)),
        "obj" => obj::read_obj(path).map(drop).map_err(|e| shown(&e)),
        "vtu" => vtu::read_vtu(path).map(drop).map_err(|e| shown(&e)),
        "msh" => gmsh::read_msh(path).map(drop).map_err(|e| shown(&e)),
        other => panic!("no library reader {other}"),
    }
}

/// Runs every input of the library targets in child copies of this binary, many inputs each;
/// a child that dies is replaced, from the input after the one it died on.
fn run_library_targets(
    targets: &[&Target],
    work: &Path,
    only: Option<u64>,
    failures: &mut Vec<Failure>,
) {
    // job lines: reader, path; with what each one was
    let mut jobs: Vec<(&Target, u64, Vec<Edit>, PathBuf)> = Vec::new();
    for target in targets {
        let Reader::Library(_) = target.reader else {
            unreachable!()
        };
        for n in 0..target.inputs {
            let seed = seed_of(target.name, n);
            if only.is_some_and(|s| s != seed) {
                continue;
            }
            let (edits, bytes) = mutate(target, seed);
            let input = place(target, &work.join(format!("{}-{n}", target.name)), &bytes);
            jobs.push((target, seed, edits, input));
        }
    }
    let job_file = work.join("jobs.txt");
    let mut text = String::new();
    for (target, _, _, input) in &jobs {
        let Reader::Library(reader) = target.reader else {
            unreachable!()
        };
        text.push_str(&format!("{reader}\t{}\n", input.display()));
    }
    std::fs::write(&job_file, text).unwrap();
    let mut next = 0;
    while next < jobs.len() {
        let results = work.join(format!("results-{next}.txt"));
        let out = limited(&std::env::current_exe().unwrap())
            .args([
                "--exact",
                "robustness::library_readers_child",
                "--test-threads=1",
                "--quiet",
            ])
            .env(
                CHILD_JOBS,
                format!("{}\t{next}\t{}", job_file.display(), results.display()),
            )
            .output()
            .expect("run the harness child");
        let lines: Vec<String> = std::fs::read_to_string(&results)
            .unwrap_or_default()
            .lines()
            .map(String::from)
            .collect();
        let mut last_started = None;
        let mut finished = next;
        for line in &lines {
            let mut parts = line.splitn(3, '\t');
            let (kind, i) = (
                parts.next().unwrap(),
                parts.next().unwrap().parse::<usize>().unwrap(),
            );
            let message = parts.next().unwrap_or("");
            match kind {
                "start" => last_started = Some(i),
                "ok" => finished = i + 1,
                _ => {
                    finished = i + 1;
                    if let Some(f) = message_fault(message) {
                        let (target, seed, edits, _) = &jobs[i];
                        failures.push(Failure {
                            target: target.name,
                            seed: *seed,
                            edits: edits.clone(),
                            what: format!("{f}: {message}"),
                        });
                    }
                }
            }
        }
        if out.status.success() && finished >= jobs.len() {
            break;
        }
        // the child died on the input it started last
        let died = match last_started {
            Some(i) if i >= finished => i,
            _ => panic!(
                "the harness child failed before reading input {finished}: {}",
                String::from_utf8_lossy(&out.stderr)
            ),
        };
        let (target, seed, edits, _) = &jobs[died];
        failures.push(Failure {
            target: target.name,
            seed: *seed,
            edits: edits.clone(),
            what: format!(
                "the reader died (exit {:?}): {}",
                out.status.code(),
                String::from_utf8_lossy(&out.stderr)
                    .lines()
                    .rev()
                    .take(3)
                    .collect::<Vec<_>>()
                    .join(" / ")
            ),
        });
        next = died + 1;
    }
}

/// The child of [`run_library_targets`]: with `OTOATLAS_HARNESS_JOBS` it reads the listed
/// inputs from the given one on and writes `start`, then `ok` or `err` and the message, for
/// each. Without it, as a test of its own, every library target's valid file reads back.
#[test]
fn library_readers_child() {
    let Ok(spec) = std::env::var(CHILD_JOBS) else {
        let dir = tempfile::tempdir().unwrap();
        for target in targets(dir.path())
            .iter()
            .filter(|t| matches!(t.reader, Reader::Library(_)))
        {
            let Reader::Library(reader) = target.reader else {
                unreachable!()
            };
            let path = dir.path().join("valid").join(target.file);
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(&path, &target.base).unwrap();
            if let Err(e) = read_with(reader, &path) {
                panic!("{}: the valid file does not read: {e}", target.name);
            }
        }
        return;
    };
    let mut parts = spec.split('\t');
    let (jobs, from, results) = (
        parts.next().unwrap(),
        parts.next().unwrap().parse::<usize>().unwrap(),
        parts.next().unwrap(),
    );
    let mut log = std::fs::File::create(results).unwrap();
    let jobs = std::io::BufReader::new(std::fs::File::open(jobs).unwrap());
    for (i, line) in jobs.lines().enumerate().skip(from) {
        let line = line.unwrap();
        let (reader, path) = line.split_once('\t').unwrap();
        writeln!(log, "start\t{i}").unwrap();
        log.flush().unwrap();
        match read_with(reader, Path::new(path)) {
            Ok(()) => writeln!(log, "ok\t{i}").unwrap(),
            Err(e) => writeln!(log, "err\t{i}\t{}", e.replace('\n', "\\n")).unwrap(),
        }
        log.flush().unwrap();
    }
}

/// A file of the repository.
fn repo_file(rel: &str) -> Vec<u8> {
    std::fs::read(common::root().join(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

/// Small meshes the project writes, into `dir`: a box of 2×2×2 cubes as VTU (ASCII, base64)
/// and MSH, and its boundary as PLY, STL (binary, ASCII) and OBJ.
fn written_meshes(dir: &Path) -> BTreeMap<&'static str, Vec<u8>> {
    use otoatlas::mesh::io::{VolumeMesh, gmsh, obj, ply, stl, vtu};
    use otoatlas::mesh::tet::BoundaryOf;
    let grid = common::BoxMesh::new([2.0, 1.5, 1.0], [2, 2, 2]);
    let tets = otoatlas::mesh::TetMesh {
        regions: vec![1; grid.tets.len()],
        nodes: grid.nodes,
        tets: grid.tets,
    };
    let surface = tets.boundary(BoundaryOf::Whole).surface;
    let volume = VolumeMesh::from_tets(tets);
    let attrs = ply::VertexAttributes {
        quality: Some(vec![0.25; surface.vertices.len()]),
        colors: None,
    };
    let p = |name: &str| dir.join(name);
    std::fs::create_dir_all(dir).unwrap();
    vtu::write_vtu(&p("a.vtu"), &volume, &[], vtu::VtuEncoding::Ascii).unwrap();
    vtu::write_vtu(&p("b.vtu"), &volume, &[], vtu::VtuEncoding::Base64).unwrap();
    gmsh::write_msh(
        &p("c.msh"),
        &volume,
        &BTreeMap::from([(1, "bone".to_string())]),
    )
    .unwrap();
    ply::write_ply(&p("d.ply"), &surface, &attrs).unwrap();
    stl::write_stl(&p("e.stl"), &surface, stl::StlEncoding::Binary).unwrap();
    stl::write_stl(&p("f.stl"), &surface, stl::StlEncoding::Ascii).unwrap();
    obj::write_obj(&p("g.obj"), &surface).unwrap();
    [
        "a.vtu", "b.vtu", "c.msh", "d.ply", "e.stl", "f.stl", "g.obj",
    ]
    .into_iter()
    .map(|n| (n, std::fs::read(p(n)).unwrap()))
    .collect()
}

/// The uncompressed NIfTI of sample case-002.
fn sample_nifti() -> Vec<u8> {
    use std::io::Read;
    let gz = repo_file("sample_cases/case-002/image.nii.gz");
    let mut nii = Vec::new();
    flate2::read::GzDecoder::new(&gz[..])
        .read_to_end(&mut nii)
        .unwrap();
    nii
}

/// Every target, scaled by `OTOATLAS_HARNESS_SCALE` (default 1: about 5,000 inputs). `work`
/// holds the files some targets are made from (written meshes, the package).
fn targets(work: &Path) -> Vec<Target> {
    let meshes = written_meshes(&work.join("written"));
    let slices: Vec<PathBuf> = {
        let mut v: Vec<PathBuf> =
            std::fs::read_dir(common::root().join("sample_cases/case-002/dicom"))
                .unwrap()
                .map(|e| e.unwrap().path())
                .collect();
        v.sort();
        v
    };
    let target = |name, base, format, file, reader, inputs| Target {
        name,
        base,
        format,
        file,
        folder: None,
        gzip: false,
        reader,
        inputs,
    };
    let inspect = Reader::Cli {
        args: &["inspect", "{}"],
        faults_exit_1: false,
    };
    let lib = Reader::Library;
    let mesh = |name: &str| meshes[name].clone();
    let mut all = vec![
        target(
            "dicom",
            std::fs::read(&slices[0]).unwrap(),
            Format::Dicom,
            "slice.dcm",
            inspect,
            1200,
        ),
        target(
            "nifti",
            sample_nifti(),
            Format::Nifti,
            "image.nii",
            inspect,
            700,
        ),
        Target {
            gzip: true,
            ..target(
                "nifti-gz",
                sample_nifti(),
                Format::Nifti,
                "image.nii.gz",
                inspect,
                200,
            )
        },
        target(
            "nifti-gz-stream",
            repo_file("sample_cases/case-002/image.nii.gz"),
            Format::Binary,
            "image.nii.gz",
            inspect,
            150,
        ),
        target(
            "config",
            repo_file("pipeline.toml"),
            Format::Text,
            "pipeline.toml",
            Reader::Cli {
                args: &[
                    "--config",
                    "{}",
                    "inspect",
                    "sample_cases/case-002/image.nii.gz",
                ],
                faults_exit_1: false,
            },
            400,
        ),
        Target {
            folder: Some(common::root().join("assets/atlas")),
            ..target(
                "atlas-json",
                repo_file("assets/atlas/atlas.json"),
                Format::Text,
                "atlas.json",
                Reader::Cli {
                    args: &["atlas", "info", "--atlas", "{}"],
                    faults_exit_1: false,
                },
                250,
            )
        },
        target(
            "landmarks-fcsv",
            repo_file("sample_cases/case-002/landmarks.fcsv"),
            Format::Text,
            "landmarks.fcsv",
            lib("landmarks"),
            300,
        ),
        target(
            "landmarks-mrk",
            repo_file("sample_cases/case-002/landmarks.mrk.json"),
            Format::Text,
            "landmarks.mrk.json",
            lib("landmarks"),
            300,
        ),
        target(
            "landmarks-json",
            repo_file("sample_cases/case-002/landmarks.json"),
            Format::Text,
            "landmarks.json",
            lib("landmarks"),
            300,
        ),
        target(
            "vtu-ascii",
            mesh("a.vtu"),
            Format::Text,
            "mesh.vtu",
            lib("vtu"),
            250,
        ),
        target(
            "vtu-base64",
            mesh("b.vtu"),
            Format::Text,
            "mesh.vtu",
            lib("vtu"),
            250,
        ),
        target(
            "msh",
            mesh("c.msh"),
            Format::Text,
            "mesh.msh",
            lib("msh"),
            250,
        ),
        target(
            "ply",
            mesh("d.ply"),
            Format::Text,
            "mesh.ply",
            lib("ply"),
            250,
        ),
        target(
            "stl-binary",
            mesh("e.stl"),
            Format::Binary,
            "mesh.stl",
            lib("stl"),
            200,
        ),
        target(
            "stl-ascii",
            mesh("f.stl"),
            Format::Text,
            "mesh.stl",
            lib("stl"),
            200,
        ),
        target(
            "obj",
            mesh("g.obj"),
            Format::Text,
            "mesh.obj",
            lib("obj"),
            250,
        ),
    ];
    let scale: f64 = std::env::var(SCALE)
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1.0);
    for t in &mut all {
        t.inputs = ((t.inputs as f64 * scale).ceil() as usize).max(1);
    }
    all
}

/// The package target: a sample case's package, its manifest mutated, read by `verify`.
fn package_target(work: &Path) -> Target {
    let out = work.join("run");
    let config = common::config_without_validation(work);
    let run = common::otoatlas(&[
        "--quiet",
        "--config",
        config.to_str().unwrap(),
        "run",
        common::root()
            .join("sample_cases/case-002")
            .to_str()
            .unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let package = out.join("package");
    Target {
        name: "manifest",
        base: std::fs::read(package.join("manifest.json")).unwrap(),
        format: Format::Text,
        file: "manifest.json",
        folder: Some(package),
        gzip: false,
        reader: Reader::Cli {
            args: &["verify", "{}"],
            faults_exit_1: true,
        },
        inputs: 150,
    }
}

/// The whole harness: several thousand inputs over every reader, none of which may panic,
/// abort, die by a signal or give an unclear message.
#[test]
#[ignore = "heavy: about 5,000 mutated inputs over every reader, a few minutes"]
fn mutated_inputs_end_in_success_or_a_typed_error() {
    let work = tempfile::tempdir().unwrap();
    let replay = std::env::var(REPLAY).ok().map(|r| {
        let (name, seed) = r.rsplit_once(':').expect("OTOATLAS_REPLAY=target:seed");
        (name.to_string(), seed.parse::<u64>().expect("a seed"))
    });
    let work_path = if replay.is_some() {
        work.keep()
    } else {
        work.path().to_path_buf()
    };
    let mut all = targets(&work_path);
    all.push(package_target(&work_path));
    if let Some((name, _)) = &replay {
        all.retain(|t| t.name == name);
        assert!(!all.is_empty(), "no target {name}");
    }
    let only = replay.as_ref().map(|r| r.1);
    let mut failures = Vec::new();
    let mut library = Vec::new();
    let mut inputs = 0;
    for target in &all {
        inputs += target.inputs;
        match target.reader {
            Reader::Cli { .. } => run_cli_target(target, &work_path, only, &mut failures),
            Reader::Library(_) => library.push(target),
        }
    }
    run_library_targets(&library, &work_path, only, &mut failures);
    if replay.is_none() && std::env::var_os(SCALE).is_none() {
        assert!(inputs >= 4000, "{inputs} inputs");
    }
    // how many per target and fault, then the first three of each target in full
    let mut counts: BTreeMap<(&str, &str), usize> = BTreeMap::new();
    for f in &failures {
        let kind = f.what.split(':').next().unwrap_or_default();
        *counts.entry((f.target, kind)).or_default() += 1;
    }
    let mut shown: BTreeMap<&str, usize> = BTreeMap::new();
    let report: Vec<String> = counts
        .iter()
        .map(|((target, kind), n)| format!("{n} x {target}: {kind}"))
        .chain(
            failures
                .iter()
                .filter(|f| {
                    let n = shown.entry(f.target).or_default();
                    *n += 1;
                    *n <= 3
                })
                .map(|f| {
            format!(
                "{}:{} ({:?}): {}\n  replay: {REPLAY}={}:{} cargo test --test pipeline robustness -- --include-ignored --nocapture",
                f.target, f.seed, f.edits, f.what, f.target, f.seed
            )
                }),
        )
        .collect();
    assert!(
        failures.is_empty(),
        "{} of {inputs} inputs failed:\n{}",
        failures.len(),
        report.join("\n")
    );
}

/// `run --out` at a folder of the user's own that holds a `report.html` and a `registered/`
/// folder (names a run writes) removed both before reading the image. It is bad usage now,
/// said before any work, and both are kept.
#[test]
fn an_out_of_the_users_own_is_never_emptied() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("notes");
    std::fs::create_dir_all(out.join("registered")).unwrap();
    std::fs::write(out.join("registered/scan.ply"), "mine").unwrap();
    std::fs::write(out.join("report.html"), "<p>mine</p>").unwrap();
    std::fs::write(out.join("todo.txt"), "mine").unwrap();
    let case = common::root().join("sample_cases/case-002");
    let run = common::otoatlas(&[
        "--quiet",
        "run",
        case.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("holds registered, report.html but no stages/ingest.json"),
        "{stderr}"
    );
    assert_eq!(
        std::fs::read_to_string(out.join("registered/scan.ply")).unwrap(),
        "mine"
    );
    assert_eq!(
        std::fs::read_to_string(out.join("report.html")).unwrap(),
        "<p>mine</p>"
    );
    assert!(!out.join("stages").exists());
}

/// `run --out` at a file, or where nothing can be written, was exit 1 (a failed case) after
/// the first stage; `batch --out` so too, after every case had failed; `landmarks --out` after
/// the image was read and every landmark typed. Each is bad usage (2), said before any work.
/// (`/proc` stands for a read-only folder: nobody, root included, can create a folder there.)
#[test]
fn an_out_that_is_a_file_or_cannot_be_written_is_bad_usage() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("a-file");
    std::fs::write(&file, "x").unwrap();
    let case = common::root().join("sample_cases/case-002");
    let cohort = common::root().join("sample_cases");
    let in_a_file = file.join("picks.fcsv");
    let runs: [(&str, &Path, &Path, &str); 7] = [
        (
            "run",
            &case,
            &file,
            "this is a file; expected an output folder",
        ),
        (
            "run",
            &case,
            Path::new("/proc/otoatlas-out"),
            "cannot write there (",
        ),
        (
            "batch",
            &cohort,
            &file,
            "this is a file; expected an output folder",
        ),
        (
            "batch",
            &cohort,
            Path::new("/proc/otoatlas-out"),
            "cannot write there (",
        ),
        (
            "landmarks",
            &case,
            dir.path(),
            "this is a folder; expected a file",
        ),
        ("landmarks", &case, &in_a_file, "a-file is not a folder"),
        (
            "landmarks",
            &case,
            Path::new("/proc/picks.fcsv"),
            "cannot write there (",
        ),
    ];
    for (command, input, out, says) in runs {
        let run = common::otoatlas(&[
            "--quiet",
            command,
            input.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(
            run.status.code(),
            Some(2),
            "{command} --out {out:?}: {stderr}"
        );
        assert!(stderr.contains(says), "{command} --out {out:?}: {stderr}");
        assert_eq!(message_fault(&stderr), None, "{stderr}");
    }
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "x");
}
