//! Clarke and Park transforms (placeholder).
