//! Shared control core placeholder (filled in below).
#![no_std]
