//! NumPy's NPY format, version 1.0 (numpy.lib.format: the magic `\x93NUMPY`, a little-endian
//! `u16` header length, a Python dict literal padded with spaces and ending in a newline so that
//! the data starts on a 64-byte boundary, then the data in C order), and NPZ, a ZIP archive
//! (PKWARE's APPNOTE.TXT) of one `.npy` entry per array, stored without compression.
//!
//! NPY holds the positions, frames × particles × 3, as `<f4` or `<f8` after the run's
//! precision: the same bits as the JSON result's numbers. NPZ holds one array per field asked
//! for: `positions`, `velocities`, `normals` (frames × particles × 3, in the run's precision),
//! `energy` (frames × 3, `<f8`, columns kinetic, gravitational, spring), `strain` (frames ×
//! springs, `<f8`), and always `times` (frames, `<f8`, seconds).
//!
//! The archive is written in one pass: each entry's CRC-32 is computed as its data goes out and
//! given afterwards in a data descriptor and the central directory, so nothing is held back.
//! Entries and the archive stay under 4 GiB (no ZIP64); a larger result is refused.

use std::io::{self, Write};

use super::Selected;
use crate::run::{Recording, Samples};
use crate::solver::Energy;

/// Writes the positions of `recording` as one NPY array.
pub(super) fn write_npy<W: Write>(recording: &Recording, selected: &Selected, w: &mut W) -> io::Result<()> {
    let positions = selected.positions.expect("checked by encode");
    let array = Array::vectors("positions", positions, recording);
    w.write_all(&array.header())?;
    array.write_data(w)
}

/// Writes every field selected of `recording`, and the frame times, as an NPZ archive.
pub(super) fn write_npz<W: Write>(recording: &Recording, selected: &Selected, w: &mut W) -> io::Result<()> {
    let (f, frames) = (selected, recording.frames.len());
    let mut arrays = Vec::new();
    for (name, samples) in [("positions", f.positions), ("velocities", f.velocities), ("normals", f.normals)]
    {
        if let Some(samples) = samples {
            arrays.push(Array::vectors(name, samples, recording));
        }
    }
    if let Some(energy) = f.energy {
        arrays.push(Array { name: "energy", shape: vec![frames, 3], data: Data::Energy(energy) });
    }
    if let Some(strain) = f.strain {
        arrays.push(Array {
            name: "strain",
            shape: vec![frames, recording.springs],
            data: Data::F64(strain),
        });
    }
    arrays.push(Array { name: "times", shape: vec![frames], data: Data::F64(&recording.frames.times) });

    let mut zip = ZipWriter { inner: w, written: 0, crc: crc32fast::Hasher::new(), entries: Vec::new() };
    for array in &arrays {
        let header = array.header();
        let size = header.len() + array.data_len();
        zip.begin_entry(&format!("{}.npy", array.name))?;
        zip.write_all(&header)?;
        array.write_data(&mut zip)?;
        zip.end_entry(size)?;
    }
    zip.finish()
}

/// One array: its name in the archive, its shape and where its values come from.
struct Array<'a> {
    name: &'static str,
    shape: Vec<usize>,
    data: Data<'a>,
}

enum Data<'a> {
    Samples(&'a Samples),
    Energy(&'a [Energy]),
    F64(&'a [f64]),
}

impl<'a> Array<'a> {
    /// A frames × particles × 3 field.
    fn vectors(name: &'static str, samples: &'a Samples, recording: &Recording) -> Self {
        Self {
            name,
            shape: vec![recording.frames.len(), recording.particles, 3],
            data: Data::Samples(samples),
        }
    }

    fn item_size(&self) -> usize {
        match self.data {
            Data::Samples(Samples::F32(_)) => 4,
            _ => 8,
        }
    }

    fn data_len(&self) -> usize {
        self.item_size() * self.shape.iter().product::<usize>()
    }

    /// The NPY 1.0 header, padded so that the data starts at a multiple of 64 bytes.
    fn header(&self) -> Vec<u8> {
        let descr = if self.item_size() == 4 { "<f4" } else { "<f8" };
        let shape = match self.shape.as_slice() {
            [n] => format!("({n},)"),
            dims => format!("({})", dims.iter().map(usize::to_string).collect::<Vec<_>>().join(", ")),
        };
        let dict = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
        let total = (10 + dict.len() + 1).next_multiple_of(64);
        let mut header = Vec::with_capacity(total);
        header.extend_from_slice(b"\x93NUMPY\x01\x00");
        header.extend_from_slice(&((total - 10) as u16).to_le_bytes());
        header.extend_from_slice(dict.as_bytes());
        header.resize(total - 1, b' ');
        header.push(b'\n');
        header
    }

    /// The values, little-endian, in C order, a frame's worth at a time.
    fn write_data<W: Write>(&self, w: &mut W) -> io::Result<()> {
        let rows = self.shape[0];
        let row = self.shape.iter().skip(1).product::<usize>();
        let mut buffer = Vec::with_capacity(self.item_size() * row);
        for k in 0..rows {
            buffer.clear();
            let scalars = k * row..(k + 1) * row;
            match self.data {
                Data::Samples(Samples::F32(v)) => {
                    v[scalars].iter().for_each(|x| buffer.extend_from_slice(&x.to_le_bytes()))
                }
                Data::Samples(Samples::F64(v)) => {
                    v[scalars].iter().for_each(|x| buffer.extend_from_slice(&x.to_le_bytes()))
                }
                Data::F64(v) => v[scalars].iter().for_each(|x| buffer.extend_from_slice(&x.to_le_bytes())),
                Data::Energy(energy) => {
                    let e = &energy[k];
                    for x in [e.kinetic, e.gravitational, e.spring] {
                        buffer.extend_from_slice(&x.to_le_bytes());
                    }
                }
            }
            w.write_all(&buffer)?;
        }
        Ok(())
    }
}

const LOCAL_HEADER: u32 = 0x0403_4b50;
const DATA_DESCRIPTOR: u32 = 0x0807_4b50;
const CENTRAL_HEADER: u32 = 0x0201_4b50;
const END_OF_CENTRAL_DIRECTORY: u32 = 0x0605_4b50;
/// ZIP 2.0: needed to extract entries with data descriptors.
const VERSION: u16 = 20;
/// General purpose flag bit 3: CRC and sizes follow the data, in a data descriptor.
const FLAG_DATA_DESCRIPTOR: u16 = 0x0008;
const METHOD_STORED: u16 = 0;
/// 1980-01-01 00:00 in MS-DOS format: the archive carries no meaningful time.
const DOS_TIME: u16 = 0;
const DOS_DATE: u16 = (1 << 5) | 1;

/// A ZIP archive of stored entries, written in one pass.
struct ZipWriter<'w, W> {
    inner: &'w mut W,
    written: u64,
    crc: crc32fast::Hasher,
    entries: Vec<Entry>,
}

struct Entry {
    name: String,
    crc: u32,
    size: u32,
    offset: u32,
}

fn too_large() -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidInput,
        "the result is more than an NPZ without ZIP64 can hold (4 GiB)",
    )
}

impl<W: Write> ZipWriter<'_, W> {
    fn raw(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.inner.write_all(bytes)?;
        self.written += bytes.len() as u64;
        Ok(())
    }

    fn offset(&self) -> io::Result<u32> {
        u32::try_from(self.written).map_err(|_| too_large())
    }

    fn begin_entry(&mut self, name: &str) -> io::Result<()> {
        let offset = self.offset()?;
        let mut header = Vec::with_capacity(30 + name.len());
        header.extend_from_slice(&LOCAL_HEADER.to_le_bytes());
        for field in [VERSION, FLAG_DATA_DESCRIPTOR, METHOD_STORED, DOS_TIME, DOS_DATE] {
            header.extend_from_slice(&field.to_le_bytes());
        }
        header.extend_from_slice(&[0; 12]); // CRC and sizes: in the data descriptor
        header.extend_from_slice(&(name.len() as u16).to_le_bytes());
        header.extend_from_slice(&0u16.to_le_bytes()); // extra field length
        header.extend_from_slice(name.as_bytes());
        self.raw(&header)?;
        self.crc = crc32fast::Hasher::new();
        self.entries.push(Entry { name: name.to_string(), crc: 0, size: 0, offset });
        Ok(())
    }

    fn end_entry(&mut self, size: usize) -> io::Result<()> {
        let size = u32::try_from(size).map_err(|_| too_large())?;
        let crc = std::mem::take(&mut self.crc).finalize();
        let entry = self.entries.last_mut().expect("an entry was begun");
        (entry.crc, entry.size) = (crc, size);
        let mut descriptor = Vec::with_capacity(16);
        for field in [DATA_DESCRIPTOR, crc, size, size] {
            descriptor.extend_from_slice(&field.to_le_bytes());
        }
        self.raw(&descriptor)
    }

    fn finish(mut self) -> io::Result<()> {
        let start = self.offset()?;
        let mut directory = Vec::new();
        for e in &self.entries {
            directory.extend_from_slice(&CENTRAL_HEADER.to_le_bytes());
            for field in [VERSION, VERSION, FLAG_DATA_DESCRIPTOR, METHOD_STORED, DOS_TIME, DOS_DATE] {
                directory.extend_from_slice(&field.to_le_bytes());
            }
            for field in [e.crc, e.size, e.size] {
                directory.extend_from_slice(&field.to_le_bytes());
            }
            // Name length, then extra field, comment, disk number, internal attributes: none.
            for field in [e.name.len() as u16, 0, 0, 0, 0] {
                directory.extend_from_slice(&field.to_le_bytes());
            }
            directory.extend_from_slice(&0u32.to_le_bytes()); // external attributes
            directory.extend_from_slice(&e.offset.to_le_bytes());
            directory.extend_from_slice(e.name.as_bytes());
        }
        let count = self.entries.len() as u16;
        let mut end = Vec::with_capacity(22);
        end.extend_from_slice(&END_OF_CENTRAL_DIRECTORY.to_le_bytes());
        for field in [0, 0, count, count] {
            end.extend_from_slice(&field.to_le_bytes());
        }
        end.extend_from_slice(&(directory.len() as u32).to_le_bytes());
        end.extend_from_slice(&start.to_le_bytes());
        end.extend_from_slice(&0u16.to_le_bytes()); // comment length
        self.raw(&directory)?;
        self.raw(&end)
    }
}

/// An entry's data: counted and added to its CRC as it goes out.
impl<W: Write> Write for ZipWriter<'_, W> {
    fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
        let n = self.inner.write(bytes)?;
        self.crc.update(&bytes[..n]);
        self.written += n as u64;
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn npy_header_is_padded_to_64_bytes_and_ends_in_a_newline() {
        let times = [0.0, 0.5];
        let array = Array { name: "times", shape: vec![2], data: Data::F64(&times) };
        let header = array.header();
        // 10 bytes of preamble and 58 of dict plus a newline: padded to 128.
        assert_eq!(header.len(), 128);
        assert_eq!(&header[..8], b"\x93NUMPY\x01\x00");
        assert_eq!(u16::from_le_bytes([header[8], header[9]]), 118);
        let dict = std::str::from_utf8(&header[10..]).unwrap();
        assert_eq!(dict.trim_end(), "{'descr': '<f8', 'fortran_order': False, 'shape': (2,), }");
        assert!(dict.ends_with('\n'));
    }
}
