//! Borrowed image views (row-major, explicit stride): 8-bit gray frames and, through the same
//! [`Plane`], the `u16` depth images.
//!
//! Frames and maps may live in external memory: views borrow, they never copy.

/// Errors building an image view.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ImageError {
    /// Width or height is zero.
    ZeroSize,
    /// The stride (bytes per row) is smaller than the width.
    StrideTooSmall {
        /// Requested stride, bytes.
        stride: usize,
        /// Image width, pixels.
        width: usize,
    },
    /// The buffer is shorter than `stride * (height - 1) + width` bytes.
    BufferTooSmall {
        /// Bytes needed.
        needed: usize,
        /// Bytes given.
        got: usize,
    },
}

impl core::fmt::Display for ImageError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::ZeroSize => write!(f, "the image has a width or height of 0 pixels; give at least 1 x 1"),
            Self::StrideTooSmall { stride, width } => write!(
                f,
                "the image's row stride ({stride} bytes) is smaller than its width ({width} pixels); give a stride of at least the width"
            ),
            Self::BufferTooSmall { needed, got } => write!(
                f,
                "the image buffer has {got} bytes, its size needs {needed}; pass the whole image or a smaller size"
            ),
        }
    }
}

impl core::error::Error for ImageError {}

fn check(len: usize, width: usize, height: usize, stride: usize) -> Result<(), ImageError> {
    if width == 0 || height == 0 {
        return Err(ImageError::ZeroSize);
    }
    if stride < width {
        return Err(ImageError::StrideTooSmall { stride, width });
    }
    let needed = stride
        .checked_mul(height - 1)
        .and_then(|n| n.checked_add(width))
        .unwrap_or(usize::MAX);
    if len < needed {
        return Err(ImageError::BufferTooSmall { needed, got: len });
    }
    Ok(())
}

/// A borrowed, read-only image of `T` pixels (row-major; `stride` in elements, which are bytes
/// for [`ImageView`]). One implementation for the gray frames ([`ImageView`], `u8`) and the
/// depth images ([`crate::reproject::DepthView`], `u16` depths).
#[derive(Clone, Copy, Debug)]
pub struct Plane<'a, T> {
    data: &'a [T],
    width: usize,
    height: usize,
    stride: usize,
}

/// A borrowed, read-only 8-bit grayscale image (`stride` in bytes).
pub type ImageView<'a> = Plane<'a, u8>;

impl<'a, T: Copy> Plane<'a, T> {
    /// A tightly packed image (`stride == width`).
    pub fn new(data: &'a [T], width: usize, height: usize) -> Result<Self, ImageError> {
        Self::with_stride(data, width, height, width)
    }

    /// An image whose rows start `stride` elements apart. Errors: a zero width or height,
    /// a stride below the width, a buffer shorter than `stride * (height - 1) + width`.
    pub fn with_stride(
        data: &'a [T],
        width: usize,
        height: usize,
        stride: usize,
    ) -> Result<Self, ImageError> {
        check(data.len(), width, height, stride)?;
        Ok(Self {
            data,
            width,
            height,
            stride,
        })
    }

    /// Width, pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height, pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Elements between the starts of two rows (bytes for [`ImageView`]).
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// The underlying buffer (rows `stride` apart).
    pub fn data(&self) -> &'a [T] {
        self.data
    }

    /// Row `y` (exactly `width` pixels), or `None` outside the image.
    pub fn row(&self, y: usize) -> Option<&'a [T]> {
        if y >= self.height {
            return None;
        }
        let start = y * self.stride;
        self.data.get(start..start + self.width)
    }

    /// Pixel at column `x`, row `y`, or `None` outside the image.
    pub fn get(&self, x: usize, y: usize) -> Option<T> {
        if x >= self.width {
            return None;
        }
        self.row(y).and_then(|r| r.get(x).copied())
    }

    /// A rectangular sub-view (shares the buffer), or `None` if it does not fit.
    pub fn sub(&self, x: usize, y: usize, width: usize, height: usize) -> Option<Self> {
        let fits = |o: usize, n: usize, limit: usize| o.checked_add(n).is_some_and(|e| e <= limit);
        if width == 0 || height == 0 || !fits(x, width, self.width) || !fits(y, height, self.height)
        {
            return None;
        }
        let start = y * self.stride + x;
        let data = self.data.get(start..)?;
        Self::with_stride(data, width, height, self.stride).ok()
    }
}

/// A borrowed, writable 8-bit grayscale image.
#[derive(Debug)]
pub struct ImageViewMut<'a> {
    data: &'a mut [u8],
    width: usize,
    height: usize,
    stride: usize,
}

impl<'a> ImageViewMut<'a> {
    /// A tightly packed image (`stride == width`).
    pub fn new(data: &'a mut [u8], width: usize, height: usize) -> Result<Self, ImageError> {
        check(data.len(), width, height, width)?;
        Ok(Self {
            data,
            width,
            height,
            stride: width,
        })
    }

    /// Width, pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height, pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Bytes between the starts of two rows.
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// Read-only view of the same pixels.
    pub fn as_view(&self) -> ImageView<'_> {
        Plane {
            data: self.data,
            width: self.width,
            height: self.height,
            stride: self.stride,
        }
    }

    /// Mutable row `y`, or `None` outside the image.
    pub fn row_mut(&mut self, y: usize) -> Option<&mut [u8]> {
        if y >= self.height {
            return None;
        }
        let start = y * self.stride;
        self.data.get_mut(start..start + self.width)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_bad_sizes() {
        let buf = [0u8; 12];
        assert_eq!(ImageView::new(&buf, 0, 3).err(), Some(ImageError::ZeroSize));
        assert_eq!(
            ImageView::new(&buf, 4, 4).err(),
            Some(ImageError::BufferTooSmall {
                needed: 16,
                got: 12
            })
        );
        assert!(matches!(
            ImageView::with_stride(&buf, 4, 3, 3),
            Err(ImageError::StrideTooSmall { .. })
        ));
    }

    #[test]
    fn rows_pixels_and_subviews() {
        let mut buf = [0u8; 12];
        for (i, b) in buf.iter_mut().enumerate() {
            *b = i as u8;
        }
        let v = ImageView::new(&buf, 4, 3).unwrap();
        assert_eq!(v.row(1), Some(&buf[4..8]));
        assert_eq!(v.get(3, 2), Some(11));
        assert_eq!(v.get(4, 0), None);
        let s = v.sub(1, 1, 2, 2).unwrap();
        assert_eq!(s.get(0, 0), Some(5));
        assert_eq!(s.get(1, 1), Some(10));
        assert!(v.sub(3, 0, 2, 1).is_none());
        // Offsets and sizes whose sum wraps are refused, not wrapped into range.
        assert!(v.sub(usize::MAX, 0, 2, 1).is_none());
        assert!(v.sub(1, 1, 1, usize::MAX).is_none());
    }
}
