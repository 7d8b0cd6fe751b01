//! The gpiocdev backend (Linux GPIO character device). Being written.
