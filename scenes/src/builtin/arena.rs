//! stub
use crate::Scene;
pub fn arena() -> Scene {
    super::small::cube()
}
