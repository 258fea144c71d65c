//! CSV reader (placeholder).
