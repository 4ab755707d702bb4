//! Every length a DICOM file's elements claim, checked against the bytes the file holds before
//! the `dicom` crate reads it. That crate reserves and fills a value's declared length before
//! reading it, so a header that lies (a transfer syntax saying big endian over a little-endian
//! body reads every length as gigabytes) took about 4 GB for a 14 KB file. This walk reads only
//! the element headers, with `dicom-parser`'s lazy reader, and skips each value without
//! buffering it.
//!
//! A deflated data set is inflated here first, under the same cap as a file
//! (`ingest.max_file_mib`), and its lengths checked against the inflated bytes: a few
//! kilobytes of deflate can claim gigabytes, and the crate inflates without a bound.

use std::fs::File;
use std::io::{BufReader, Cursor, Read, Seek, SeekFrom};
use std::path::Path;

use dicom_encoding::TransferSyntaxIndex;
use dicom_encoding::transfer_syntax::Codec;
use dicom_parser::StatefulDecode;
use dicom_parser::dataset::LazyDataToken;
use dicom_parser::dataset::lazy_read::LazyDataSetReader;
use dicom_transfer_syntax_registry::TransferSyntaxRegistry;
use dicom_transfer_syntax_registry::entries::EXPLICIT_VR_LITTLE_ENDIAN;

use crate::image::ImageError;

/// Where the file meta group starts: after the 128-byte preamble and `DICM`.
const META_START: u64 = 132;

/// Refuses `path` (of `file_bytes` bytes, with the `DICM` marker) if any element, sequence,
/// item or fragment claims more bytes than the file has left where it starts, or if its
/// deflated data set inflates to more than `max_inflated` bytes (or claims more than the
/// inflated bytes hold). Headers the lazy reader cannot follow, and transfer syntaxes that
/// the registry does not know, are left to the `dicom` crate.
pub fn check_element_lengths(
    path: &Path,
    file_bytes: u64,
    max_inflated: u64,
) -> Result<(), ImageError> {
    let io_err = |source| ImageError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut reader = BufReader::new(File::open(path).map_err(io_err)?);
    reader.seek(SeekFrom::Start(META_START)).map_err(io_err)?;
    // the file meta group is explicit VR little endian whatever the data set's syntax
    let meta = walk(
        &mut reader,
        &EXPLICIT_VR_LITTLE_ENDIAN.erased(),
        path,
        file_bytes,
        true,
    )?;
    let Some(uid) = meta.transfer_syntax else {
        return Ok(());
    };
    let Some(ts) = TransferSyntaxRegistry.get(uid.trim_end_matches(['\0', ' '])) else {
        return Ok(());
    };
    reader.seek(SeekFrom::Start(meta.end)).map_err(io_err)?;
    match ts.codec() {
        Codec::None | Codec::EncapsulatedPixelData(..) => {
            walk(&mut reader, ts, path, file_bytes, false).map(drop)
        }
        // a data set stored through a codec (deflated, explicit VR little endian inside) has
        // the lengths of the inflated bytes
        Codec::Dataset(_) => {
            let inflated = inflate_capped(&mut reader, max_inflated, path)?;
            let inflated_bytes = inflated.len() as u64;
            let inner = EXPLICIT_VR_LITTLE_ENDIAN.erased();
            walk(
                &mut Cursor::new(inflated),
                &inner,
                path,
                inflated_bytes,
                false,
            )
            .map(drop)
        }
    }
}

/// The raw deflate stream from the reader's position, inflated, if it is no more than `cap`
/// bytes: counted first without keeping anything, then inflated into a buffer of that size.
fn inflate_capped(
    reader: &mut BufReader<File>,
    cap: u64,
    path: &Path,
) -> Result<Vec<u8>, ImageError> {
    let start = reader.stream_position().unwrap_or(META_START);
    let corrupt = |e: std::io::Error| ImageError::DicomParse {
        path: path.to_path_buf(),
        message: format!("the deflated data set does not inflate: {e}"),
    };
    let mut counting = flate2::read::DeflateDecoder::new(&mut *reader).take(cap.saturating_add(1));
    let size = std::io::copy(&mut counting, &mut std::io::sink()).map_err(corrupt)?;
    if size > cap {
        return Err(ImageError::InflatesTooLarge {
            path: path.to_path_buf(),
            max_mib: cap as f64 / 1048576.0,
        });
    }
    reader
        .seek(SeekFrom::Start(start))
        .map_err(|source| ImageError::Io {
            path: path.to_path_buf(),
            source,
        })?;
    let mut inflated = Vec::with_capacity(size as usize);
    flate2::read::DeflateDecoder::new(reader)
        .take(size)
        .read_to_end(&mut inflated)
        .map_err(corrupt)?;
    Ok(inflated)
}

/// What walking the meta group found.
struct Walked {
    /// Where the walk stopped: the end of the last element it passed.
    end: u64,
    /// The Transfer Syntax UID (0002,0010), when walking the meta group.
    transfer_syntax: Option<String>,
}

/// Walks the elements from the reader's position; with `meta`, only group 0002 (and keeps the
/// transfer syntax UID).
fn walk<R: Read + Seek>(
    reader: &mut R,
    ts: &dicom_encoding::TransferSyntax,
    path: &Path,
    file_bytes: u64,
    meta: bool,
) -> Result<Walked, ImageError> {
    let start = reader.stream_position().unwrap_or(META_START);
    let mut walked = Walked {
        end: start,
        transfer_syntax: None,
    };
    let Ok(mut tokens) = LazyDataSetReader::new_with_ts(reader, ts) else {
        return Ok(walked);
    };
    let too_long = |what: &'static str, len: u32, at: u64| ImageError::BadValue {
        path: path.to_path_buf(),
        tag: what,
        value: format!("{len} bytes at byte {at}"),
        expected: format!(
            "no more than the {} bytes left in the file (is its transfer syntax right?)",
            file_bytes.saturating_sub(at)
        ),
    };
    while let Some(token) = tokens.advance() {
        let Ok(token) = token else {
            break;
        };
        match token {
            LazyDataToken::LazyValue { header, decoder } => {
                if meta && header.tag.group() != 0x0002 {
                    break;
                }
                let at = decoder.position();
                if header.len.is_defined()
                    && u64::from(header.len.0) > file_bytes.saturating_sub(at)
                {
                    return Err(too_long("element length", header.len.0, at));
                }
                if meta && header.tag == dicom_dictionary_std::tags::TRANSFER_SYNTAX_UID {
                    let Ok(value) = decoder.read_value(&header) else {
                        break;
                    };
                    walked.transfer_syntax = Some(value.to_str().into_owned());
                } else if decoder.skip_bytes(header.len.0).is_err() {
                    break;
                }
                walked.end = decoder.position();
            }
            LazyDataToken::LazyItemValue { len, decoder } => {
                let at = decoder.position();
                if u64::from(len) > file_bytes.saturating_sub(at) {
                    return Err(too_long("item length", len, at));
                }
                if decoder.skip_bytes(len).is_err() {
                    break;
                }
                walked.end = decoder.position();
            }
            LazyDataToken::SequenceStart { tag, len } => {
                if meta && tag.group() != 0x0002 {
                    break;
                }
                if len.is_defined() && u64::from(len.0) > file_bytes.saturating_sub(walked.end) {
                    return Err(too_long("sequence length", len.0, walked.end));
                }
            }
            LazyDataToken::ItemStart { len }
                if len.is_defined() && u64::from(len.0) > file_bytes.saturating_sub(walked.end) =>
            {
                return Err(too_long("item length", len.0, walked.end));
            }
            LazyDataToken::ElementHeader(header) if meta && header.tag.group() != 0x0002 => {
                break;
            }
            _ => {}
        }
    }
    Ok(walked)
}
