//! One module per subcommand: its argument struct and its `run`.

pub mod collide;
pub mod demo;
pub mod fk;
pub mod ik;
pub mod inspect;
pub mod listen;
pub mod robot;
pub mod schema;
pub mod solve;
pub mod view;
