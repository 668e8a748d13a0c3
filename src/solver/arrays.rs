//! `K` arrays of one length in one allocation, each starting on its own cache line.
//!
//! A structure-of-arrays loop reads element `p` of many arrays at once: an implicit product
//! reads a spring family's four coupling arrays, three axes of `x` and three of `y` in one pass.
//! Two things about where those arrays lie cost time:
//!
//! - **Alignment.** The allocator's large blocks start 16 bytes into a page, so every other
//!   32-byte vector load of an `f32` array so placed straddles two cache lines and costs two.
//!   Here every array starts on a cache line.
//! - **Sets.** Large arrays allocated one by one each get a fresh mapping and so all start at the
//!   same offset within a page: element `p` of every array then falls at the same place in the
//!   caches, and a pass over more arrays than a cache set has ways can evict its own lines. Here
//!   array `k` starts `k` cache lines further round the page than array 0.
//!
//! Arrays shorter than a page are simply packed, each rounded up to whole cache lines. The layout
//! changes no arithmetic, so no result. What each part gained is in `docs/decisions.md`.

use std::ops::{Index, IndexMut};

use crate::solver::math::real::Real;

/// The bytes of a cache line and of a page, the granularities the layout staggers by.
const LINE_BYTES: usize = 64;
const PAGE_BYTES: usize = 4096;

/// `K` arrays of `len` elements (see the module docs).
#[derive(Debug)]
pub struct Arrays<T, const K: usize> {
    /// The arrays, after `start` elements that bring array 0 to a cache line.
    data: Vec<T>,
    start: usize,
    len: usize,
    /// Elements from the start of one array to the start of the next.
    stride: usize,
}

impl<T: Real, const K: usize> Arrays<T, K> {
    /// `K` arrays of `len` zeros.
    pub fn zeros(len: usize) -> Self {
        let size = std::mem::size_of::<T>();
        let (line, page) = (LINE_BYTES / size, PAGE_BYTES / size);
        let stride = if len >= page { len.next_multiple_of(page) + line } else { len.next_multiple_of(line) };
        // A line's worth of slack: the block itself is aligned only to `T`.
        let data = vec![T::ZERO; stride * K + line];
        let address = data.as_ptr() as usize;
        let start = (address.next_multiple_of(LINE_BYTES) - address) / size;
        Self { data, start, len, stride }
    }

    /// The arrays `arrays`, which have one length, laid out as described in the module docs.
    pub fn from_arrays(arrays: [Vec<T>; K]) -> Self {
        let mut laid_out = Self::zeros(arrays[0].len());
        for (to, from) in laid_out.iter_mut().zip(&arrays) {
            to.copy_from_slice(from);
        }
        laid_out
    }

    /// The length of each array.
    #[inline]
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the arrays are empty.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Every array.
    #[inline]
    pub fn arrays(&self) -> [&[T]; K] {
        std::array::from_fn(|k| &self[k])
    }

    /// Every array, to write.
    #[inline]
    pub fn arrays_mut(&mut self) -> [&mut [T]; K] {
        let (len, stride) = (self.len, self.stride);
        let mut chunks = self.data[self.start..].chunks_exact_mut(stride.max(1));
        std::array::from_fn(|_| match chunks.next() {
            Some(chunk) => &mut chunk[..len],
            None => &mut [],
        })
    }

    /// The arrays in order.
    pub fn iter(&self) -> std::array::IntoIter<&[T], K> {
        self.arrays().into_iter()
    }

    /// The arrays in order, to write.
    pub fn iter_mut(&mut self) -> std::array::IntoIter<&mut [T], K> {
        self.arrays_mut().into_iter()
    }
}

/// A clone's block may sit differently from the original's: its arrays are moved to start on a
/// cache line again.
impl<T: Clone, const K: usize> Clone for Arrays<T, K> {
    fn clone(&self) -> Self {
        if self.data.is_empty() {
            return Self::default();
        }
        let mut data = self.data.clone();
        let (size, address) = (std::mem::size_of::<T>(), data.as_ptr() as usize);
        let start = (address.next_multiple_of(LINE_BYTES) - address) / size.max(1);
        // The slack before and after the arrays is one line in all, so either rotation only moves
        // slack round the ends.
        if start > self.start {
            data.rotate_right(start - self.start);
        } else {
            data.rotate_left(self.start - start);
        }
        Self { data, start, len: self.len, stride: self.stride }
    }
}

/// No arrays' worth of elements: every array empty.
impl<T, const K: usize> Default for Arrays<T, K> {
    fn default() -> Self {
        Self { data: Vec::new(), start: 0, len: 0, stride: 0 }
    }
}

impl<T, const K: usize> Index<usize> for Arrays<T, K> {
    type Output = [T];

    #[inline(always)]
    fn index(&self, k: usize) -> &[T] {
        assert!(k < K, "array {k} of {K}");
        let first = self.start + k * self.stride;
        &self.data[first..first + self.len]
    }
}

impl<T, const K: usize> IndexMut<usize> for Arrays<T, K> {
    #[inline(always)]
    fn index_mut(&mut self, k: usize) -> &mut [T] {
        assert!(k < K, "array {k} of {K}");
        let first = self.start + k * self.stride;
        &mut self.data[first..first + self.len]
    }
}

impl<'a, T: Real, const K: usize> IntoIterator for &'a Arrays<T, K> {
    type Item = &'a [T];
    type IntoIter = std::array::IntoIter<&'a [T], K>;

    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

impl<'a, T: Real, const K: usize> IntoIterator for &'a mut Arrays<T, K> {
    type Item = &'a mut [T];
    type IntoIter = std::array::IntoIter<&'a mut [T], K>;

    fn into_iter(self) -> Self::IntoIter {
        self.iter_mut()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Where array `k`'s element `p` lies within its page, in cache lines.
    fn line_in_page<const K: usize>(arrays: &Arrays<f32, K>, k: usize, p: usize) -> usize {
        arrays[k][p..].as_ptr() as usize % PAGE_BYTES / LINE_BYTES
    }

    #[test]
    fn every_array_starts_on_a_cache_line_and_so_does_every_clone() {
        for len in [1, 7, 100, 1024, 4096, 65_536, 16_641] {
            let arrays = Arrays::<f32, 4>::zeros(len);
            let copy = Arrays::<f64, 3>::from_arrays(std::array::from_fn(|k| vec![k as f64; len])).clone();
            let starts =
                arrays.iter().map(|a| a.as_ptr() as usize).chain(copy.iter().map(|a| a.as_ptr() as usize));
            for address in starts {
                assert_eq!(address % LINE_BYTES, 0, "len {len}");
            }
            assert!(copy.iter().enumerate().all(|(k, a)| a.len() == len && a.iter().all(|&v| v == k as f64)));
        }
        let empty = Arrays::<f32, 3>::default().clone();
        assert!(empty.iter().all(<[f32]>::is_empty));
    }

    #[test]
    fn the_same_element_of_each_large_array_is_on_a_different_line_of_the_page() {
        for len in [1024, 4096, 65_536, 65_537, 16_641] {
            let arrays = Arrays::<f32, 6>::zeros(len);
            let lines: Vec<usize> = (0..6).map(|k| line_in_page(&arrays, k, len / 2)).collect();
            let mut distinct = lines.clone();
            distinct.sort_unstable();
            distinct.dedup();
            assert_eq!(distinct.len(), 6, "len {len}: lines {lines:?}");
        }
    }

    #[test]
    fn arrays_keep_their_values_apart() {
        let mut arrays = Arrays::<f64, 3>::from_arrays([vec![1.0, 2.0], vec![3.0, 4.0], vec![5.0, 6.0]]);
        arrays[1][0] = -3.0;
        let [a, b, c] = arrays.arrays_mut();
        a[1] += 10.0;
        c[0] = b[1];
        assert_eq!(arrays.arrays(), [&[1.0, 12.0][..], &[-3.0, 4.0][..], &[4.0, 6.0][..]]);
        assert_eq!(arrays.len(), 2);
        assert!(Arrays::<f32, 4>::zeros(0).iter().all(|a| a.is_empty()));
    }
}
