//! stub
use crate::Scene;
pub fn grove() -> Scene {
    super::small::cube()
}
