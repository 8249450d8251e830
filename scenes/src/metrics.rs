//! Error metrics between images.
