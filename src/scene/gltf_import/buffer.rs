//! The bytes every part of the glTF importer reads: one type, below all of them, so that the
//! container, the accessor readers and the decoders share it without importing each other.

use std::borrow::Cow;

/// A glTF buffer's bytes: borrowed from a GLB's binary chunk, owned when read from a file or a
/// `data:` URI or written by the meshopt decoder.
pub(crate) type Buffer<'a> = Cow<'a, [u8]>;
