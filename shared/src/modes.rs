//! The named modes stored in `Params` as `u32` ids (fade, mip, angle index, tree cull, ...):
//! one declaration gives the enum, `ALL` in id order, `from_id`, `name`, `cite`, `from_name` and
//! the `(name, id)` list the parameter table's choices come from (`registry.rs`). The id is
//! what the uniform carries to WGSL; the name is what users write (CLI, sweep files, CSVs).

/// Declares a mode enum (module docs). Ids must run `0, 1, 2, ...` in declaration order
/// (`from_id` indexes `ALL`); a compile-time assertion in each declaration holds it to that.
/// (This file imports no mode, so that the files declaring them may import it.)
macro_rules! modes {
    (@cite) => { None };
    (@cite $cite:literal) => { Some($cite) };
    (
        $(#[$meta:meta])*
        pub enum $ty:ident {
            $( $(#[$vmeta:meta])* $variant:ident = $id:literal => $name:literal $(($cite:literal))?, )+
        }
    ) => {
        $(#[$meta])*
        #[repr(u32)]
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum $ty {
            $( $(#[$vmeta])* $variant = $id, )+
        }

        const _: () = {
            let ids = [$($id),+];
            let mut i = 0;
            while i < ids.len() {
                assert!(ids[i] == i as u32, "mode ids must run 0, 1, 2, ... in declaration order");
                i += 1;
            }
        };

        impl $ty {
            /// Every mode, in id order.
            pub const ALL: [$ty; [$($id),+].len()] = [$($ty::$variant),+];
            /// The mode with this id, if any.
            pub fn from_id(id: u32) -> Option<Self> {
                Self::ALL.get(id as usize).copied()
            }
            /// Name used on the command line, in sweep files, CSVs and golden file names.
            pub fn name(self) -> &'static str {
                match self {
                    $( $ty::$variant => $name, )+
                }
            }
            /// The source the parameter's `--help` cites beside the name, if any (written
            /// `Variant = id => "name" ("cite"),` in the declaration).
            pub fn cite(self) -> Option<&'static str> {
                match self {
                    $( $ty::$variant => $crate::modes::modes!(@cite $($cite)?), )+
                }
            }
            /// Parses the name ([`Self::name`]).
            pub fn from_name(name: &str) -> Option<Self> {
                Self::ALL.into_iter().find(|m| m.name() == name)
            }
            /// `(name, id)` of every mode, in id order: a choice of the parameter table.
            pub fn choices() -> Vec<(&'static str, u32)> {
                Self::ALL.map(|m| (m.name(), m as u32)).to_vec()
            }
        }
    };
}
pub(crate) use modes;
