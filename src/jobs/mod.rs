//! Many renders planned as data: the views of one model ([`views`]), the jobs of a batch over
//! many models ([`batch`]) and the tiles of one image ([`tiles`]). Each plans what to render
//! and what to write where; rendering itself is [`crate::render`]'s, writing [`crate::output`]'s.

pub mod batch;
pub mod lock;
pub mod tiles;
pub mod views;
