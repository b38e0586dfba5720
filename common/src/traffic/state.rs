//! The per-step vehicle state as a structure of arrays, double-buffered: a step reads the
//! current [`Kinematics`] and writes the next one (in disjoint per-thread windows, see
//! [`KinematicsMut::split_at`]); committing is a swap, not a copy.

use super::manoeuvre::LaneChange;

macro_rules! kinematics {
    ($($field:ident : $ty:ty),* $(,)?) => {
        /// One vehicle's per-step state as a value (what the step kernel computes).
        #[derive(Debug, Clone, Copy, Default)]
        pub(crate) struct Next {
            $(pub $field: $ty,)*
        }

        /// Per-step state of every vehicle, one array per field.
        #[derive(Debug, Clone, Default)]
        pub(crate) struct Kinematics {
            $(pub $field: Vec<$ty>,)*
        }

        /// A mutable window into a [`Kinematics`]: one thread's share of the next state.
        pub(crate) struct KinematicsMut<'a> {
            $(pub $field: &'a mut [$ty],)*
        }

        impl Kinematics {
            pub(crate) fn reserve(&mut self, n: usize) {
                $(self.$field.reserve(n);)*
            }
            pub(crate) fn push(&mut self, v: &Next) {
                $(self.$field.push(v.$field);)*
            }
            #[inline]
            pub(crate) fn get(&self, i: usize) -> Next {
                Next { $($field: self.$field[i],)* }
            }
            #[inline]
            pub(crate) fn set(&mut self, i: usize, v: &Next) {
                $(self.$field[i] = v.$field;)*
            }
            pub(crate) fn resize(&mut self, n: usize) {
                $(self.$field.resize(n, Default::default());)*
            }
            pub(crate) fn view(&mut self) -> KinematicsMut<'_> {
                KinematicsMut { $($field: &mut self.$field,)* }
            }
        }

        impl<'a> KinematicsMut<'a> {
            /// Splits into `[0, k)` and `[k, len)`.
            pub(crate) fn split_at(self, k: usize) -> (KinematicsMut<'a>, KinematicsMut<'a>) {
                $(let $field = self.$field.split_at_mut(k);)*
                (KinematicsMut { $($field: $field.0,)* }, KinematicsMut { $($field: $field.1,)* })
            }
            #[inline]
            pub(crate) fn set(&mut self, k: usize, v: &Next) {
                $(self.$field[k] = v.$field;)*
            }
        }
    };
}

kinematics! {
    s_m: f64,
    d_m: f64,
    d_rate_mps: f64,
    speed_mps: f64,
    accel_mps2: f64,
    x_m: f64,
    y_m: f64,
    cos_h: f64,
    sin_h: f64,
    lane: u32,
    seg: u32,
    lane_change: LaneChange,
    manoeuvre_started: bool,
    active: bool,
    intrude: u8,
}

impl KinematicsMut<'_> {
    pub(crate) fn len(&self) -> usize {
        self.s_m.len()
    }
}
