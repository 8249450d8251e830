//! Placeholder until the builder branch lands.
use crate::KdTree;
impl KdTree {
    /// Structural check (placeholder).
    pub fn validate(&self) -> Result<(), String> {
        Ok(())
    }
}
