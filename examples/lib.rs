//! Examples of the tilting crates; see the files next to this one. This library is empty.
