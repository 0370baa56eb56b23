//! The named modes stored in [`crate::Params`] as `u32` ids (fade, mip, angle index, tree cull):
//! one declaration gives the enum, `ALL` in id order, `from_id`, `name`, `from_name` and the
//! `(name, id)` list the parameter table's choices come from ([`crate::registry`]). The id is
//! what the uniform carries to WGSL; the name is what users write (CLI, sweep files, CSVs).

/// Declares a mode enum (module docs). Ids must run `0, 1, 2, ...` in declaration order
/// (`from_id` indexes `ALL`); `tests::ids_index_all` holds every mode to it.
macro_rules! modes {
    (
        $(#[$meta:meta])*
        pub enum $ty:ident {
            $( $(#[$vmeta:meta])* $variant:ident = $id:literal => $name:literal, )+
        }
    ) => {
        $(#[$meta])*
        #[repr(u32)]
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum $ty {
            $( $(#[$vmeta])* $variant = $id, )+
        }

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

#[cfg(test)]
mod tests {
    use crate::{AngleIndexMode, FadeMode, Hierarchy, MipMode, TreeCull};

    fn check(choices: Vec<(&'static str, u32)>) {
        for (i, (name, id)) in choices.iter().enumerate() {
            assert_eq!(*id as usize, i, "{name}: ids must run 0, 1, 2, ...");
        }
    }

    #[test]
    fn ids_index_all() {
        check(FadeMode::choices());
        check(MipMode::choices());
        check(AngleIndexMode::choices());
        check(TreeCull::choices());
        check(Hierarchy::choices());
        assert_eq!(
            MipMode::from_name("coverage"),
            Some(MipMode::CoveragePreserving)
        );
        assert_eq!(TreeCull::from_id(2), Some(TreeCull::All));
        assert_eq!(AngleIndexMode::from_id(2), None);
    }
}
