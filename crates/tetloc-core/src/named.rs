//! Enums that go by name on the command line, in Python and in file names: [`named!`](crate::named!)
//! declares one from a table of its values and their names, so that the names are written
//! once for `name`, `Display` and `FromStr`; [`display_name!`](crate::display_name!) shows
//! any type with a `name` as that name.

/// Declares an enum that goes by name, one line a value (`Variant => "name"`, aliases after
/// `|`; names in lower case): the enum, `ALL` (every value, in the table's order), `name`
/// (the first name), `Display` (the name) and `FromStr` (any of the names, trimmed, in any
/// case; another is an `Error::Invalid`, or with `Err = String` its message, that lists the
/// names and says what, `$what`, it is not).
#[macro_export]
macro_rules! named {
    (@err) => { $crate::Error };
    (@err $err:ty) => { $err };
    (
        $(#[$meta:meta])*
        $vis:vis enum $name:ident: $what:literal $(, Err = $err:ty)? {
            $( $(#[$vmeta:meta])* $variant:ident => $text:literal $(| $alias:literal)*, )*
        }
    ) => {
        $(#[$meta])*
        $vis enum $name {
            $( $(#[$vmeta])* $variant, )*
        }

        impl $name {
            /// Every value, in the order of the names' table.
            pub const ALL: [$name; [$($text),*].len()] = [$($name::$variant),*];

            /// What the command line and Python call it.
            pub fn name(self) -> &'static str {
                match self {
                    $( $name::$variant => $text, )*
                }
            }
        }

        $crate::display_name!($name);

        impl ::std::str::FromStr for $name {
            type Err = $crate::named!(@err $($err)?);
            fn from_str(s: &str) -> ::std::result::Result<$name, Self::Err> {
                match s.trim().to_ascii_lowercase().as_str() {
                    $( $text $(| $alias)* => Ok($name::$variant), )*
                    _ => Err($crate::named::Unknown::unknown($what, s, &$name::ALL.map($name::name))),
                }
            }
        }
    };
}

/// `Display` for types with a `name(self) -> &'static str`: the name, padded as the format
/// asks (`{:<10}`).
#[macro_export]
macro_rules! display_name {
    ($($t:ty),+ $(,)?) => {$(
        impl ::std::fmt::Display for $t {
            fn fmt(&self, f: &mut ::std::fmt::Formatter<'_>) -> ::std::fmt::Result {
                f.pad(self.name())
            }
        }
    )+};
}

/// The error for a name that is none of `names`, of a `what`: its message is
/// `unknown shape 'torus' (known: jets, fusion, agulhas, japan)`.
pub trait Unknown {
    fn unknown(what: &str, name: &str, names: &[&str]) -> Self;
}

impl Unknown for String {
    fn unknown(what: &str, name: &str, names: &[&str]) -> String {
        format!("unknown {what} '{name}' (known: {})", names.join(", "))
    }
}

impl Unknown for crate::Error {
    fn unknown(what: &str, name: &str, names: &[&str]) -> crate::Error {
        crate::Error::Invalid(String::unknown(what, name, names))
    }
}
