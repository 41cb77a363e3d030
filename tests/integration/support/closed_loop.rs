//! The PI speed loop of docs/model.md §3 written out again for the tests: the linear 5-state loop
//! (A_cl, D_1, L_c), its impulse response h(s) = L_c e^{A_cl s} D_1 with the sign changes
//! located, and the continuous-time loop with and without backlash driven by a sinusoidal
//! speed reference. All integration goes through the Taylor integrator of `taylor.rs`.

use super::reference::GenericForm;
use super::taylor::{backlash_modes, component, integrate_poly, Coeffs, Event, Guard, Hybrid, Mode, Piece, ORDER};

/// z_cl = [θ_m, ω_m, θ_L, ω_L, x_c] (docs/model.md §3).
#[derive(Clone, Copy, Debug)]
pub struct LinearLoop {
    pub a: [[f64; 5]; 5],
    pub d1: [f64; 5],
    pub lc: [f64; 5],
    /// K g: the bound on |φ|.
    pub kg: f64,
    /// Kp = Ki = 0: open loop, the bounds use the 4-state plant (docs/model.md §4).
    pub open_loop: bool,
}

impl LinearLoop {
    /// A_cl = [A_p − B_p Kp L_1, B_p Ki; −L_1, 0], D_1 = [0, r_m/J_m, 0, −r_L/J_L, 0], L_c picks ω_L.
    pub fn new(f: &GenericForm, kp: f64, ki: f64) -> LinearLoop {
        let mut a = [[0.0; 5]; 5];
        a[0][1] = 1.0;
        a[1][0] = -f.k * f.r_m * f.r_m / f.j_m;
        a[1][1] = -(f.b_m + kp) / f.j_m;
        a[1][2] = f.k * f.r_m * f.r_l / f.j_m;
        a[1][4] = ki / f.j_m;
        a[2][3] = 1.0;
        a[3][0] = f.k * f.r_m * f.r_l / f.j_l;
        a[3][2] = -f.k * f.r_l * f.r_l / f.j_l;
        a[3][3] = -f.b_l / f.j_l;
        a[4][1] = -1.0;
        LinearLoop {
            a,
            d1: [0.0, f.r_m / f.j_m, 0.0, -f.r_l / f.j_l, 0.0],
            lc: [0.0, 0.0, 0.0, 1.0, 0.0],
            kg: f.k * f.g,
            open_loop: kp == 0.0 && ki == 0.0,
        }
    }

    /// K g ‖v‖₂ over the 4 plant entries in open loop, all 5 in closed loop.
    pub fn paper_norm(&self, v: &[f64; 5]) -> f64 {
        let n = if self.open_loop { 4 } else { 5 };
        self.kg * v[..n].iter().map(|x| x * x).sum::<f64>().sqrt()
    }
}

/// Follows x(s) = e^{A s} D_1 and accumulates ∫|h|, ∫ x ds, and the sign changes of h.
pub struct ImpulseResponse {
    sys: Hybrid<5>,
    lc: [f64; 5],
    mode: usize,
    pub x: [f64; 5],
    pub elapsed: f64,
    /// ∫_0^elapsed |h(s)| ds.
    pub l1: f64,
    /// ∫_0^elapsed e^{A s} D_1 ds.
    pub integral: [f64; 5],
    /// Times s where h changes sign.
    pub sign_changes: Vec<f64>,
}

impl ImpulseResponse {
    pub fn new(lp: &LinearLoop) -> ImpulseResponse {
        // Mode 0: h ≤ 0, mode 1: h > 0; the same dynamics, a guard on each sign change.
        let neg: [f64; 5] = std::array::from_fn(|i| -lp.lc[i]);
        let modes = vec![
            Mode {
                a: lp.a,
                c: [0.0; 5],
                guards: vec![Guard {
                    l: lp.lc,
                    offset: 0.0,
                    to: 1,
                    snap: None,
                }],
            },
            Mode {
                a: lp.a,
                c: [0.0; 5],
                guards: vec![Guard {
                    l: neg,
                    offset: 0.0,
                    to: 0,
                    snap: None,
                }],
            },
        ];
        let h0: f64 = (0..5).map(|i| lp.lc[i] * lp.d1[i]).sum();
        assert!(h0 != 0.0, "h(0) = 0: pick the initial sign from a derivative");
        ImpulseResponse {
            sys: Hybrid::new(modes, 0.25),
            lc: lp.lc,
            mode: usize::from(h0 > 0.0),
            x: lp.d1,
            elapsed: 0.0,
            l1: 0.0,
            integral: [0.0; 5],
            sign_changes: Vec::new(),
        }
    }

    pub fn advance(&mut self, dt: f64) {
        let mut events: Vec<Event> = Vec::new();
        let (mut l1, mut integral) = (0.0, [0.0; 5]);
        let lc = self.lc;
        let mut on_piece = |p: Piece<5>| {
            let mut hp = [0.0; ORDER + 1];
            for n in 0..=ORDER {
                hp[n] = (0..5).map(|i| lc[i] * p.coeffs[n][i]).sum();
            }
            let sign = if p.mode == 1 { 1.0 } else { -1.0 };
            l1 += sign * integrate_poly(&hp, p.len);
            for (i, v) in integral.iter_mut().enumerate() {
                *v += integrate_poly(&component(p.coeffs, i), p.len);
            }
        };
        self.sys
            .advance(&mut self.mode, &mut self.x, dt, &|_, _| {}, &mut events, &mut on_piece);
        self.l1 += l1;
        for i in 0..5 {
            self.integral[i] += integral[i];
        }
        let start = self.elapsed;
        self.sign_changes.extend(events.iter().map(|e| start + e.offset));
        self.elapsed += dt;
    }
}

/// L_c x(t) for x' = A x + D_1 φ(τ), x(0) = 0, with φ(τ) = K g sgn h(t − τ): the worst
/// admissible disturbance of docs/model.md §3, which should produce exactly K g ∫_0^t |h|.
pub fn worst_case_response(lp: &LinearLoop, t: f64, sign_changes: &[f64], h0_positive: bool) -> f64 {
    // Sign of h on (s_j, s_{j+1}); in τ the pieces run backwards from τ = t.
    let mut breaks: Vec<f64> = sign_changes.iter().copied().filter(|&s| s < t).collect();
    breaks.sort_by(f64::total_cmp);
    let sign_at = |j: usize| if (j % 2 == 0) == h0_positive { 1.0 } else { -1.0 };
    // τ-intervals in increasing τ: [t − s_{j+1}, t − s_j] carries sign_at(j).
    let mut bounds_s = vec![0.0];
    bounds_s.extend(&breaks);
    bounds_s.push(t);
    let sys = Hybrid::new(
        vec![Mode {
            a: lp.a,
            c: [0.0; 5],
            guards: vec![],
        }],
        0.25,
    );
    let mut x = [0.0; 5];
    let mut mode = 0;
    for j in (0..bounds_s.len() - 1).rev() {
        let len = bounds_s[j + 1] - bounds_s[j];
        let phi = lp.kg * sign_at(j);
        let d1 = lp.d1;
        let forcing = move |_: f64, out: &mut Coeffs<5>| {
            for i in 0..5 {
                out[0][i] = d1[i] * phi;
            }
        };
        sys.advance(&mut mode, &mut x, len, &forcing, &mut Vec::new(), &mut |_| {});
    }
    (0..5).map(|i| lp.lc[i] * x[i]).sum()
}

/// The continuous-time PI loop on the plant of docs/model.md §1, with or without the gap:
/// y = [u, ω_m, ω_L, θ_m, θ_L, x_c], τ_m = Kp (ω_ref − ω_m) + Ki x_c, x_c' = ω_ref − ω_m,
/// ω_ref(t) = amp sin(w t), τ_L = 0.
pub struct PiLoop {
    sys: Hybrid<6>,
    pub mode: usize,
    pub y: [f64; 6],
    pub t: f64,
    j_m: f64,
    kp: f64,
    amp: f64,
    w: f64,
}

impl PiLoop {
    pub fn new(f: &GenericForm, kp: f64, ki: f64, with_gap: bool, amp: f64, w: f64) -> PiLoop {
        let g = if with_gap { f.g } else { 0.0 };
        let build = |sigma: f64, contact: bool| {
            let mut a = [[0.0; 6]; 6];
            let mut c = [0.0; 6];
            a[0][1] = f.r_m;
            a[0][2] = -f.r_l;
            a[1][1] = -(f.b_m + kp) / f.j_m;
            a[1][5] = ki / f.j_m;
            a[2][2] = -f.b_l / f.j_l;
            a[3][1] = 1.0;
            a[4][2] = 1.0;
            a[5][1] = -1.0;
            if contact {
                a[1][0] = -f.r_m * f.k / f.j_m;
                a[2][0] = f.r_l * f.k / f.j_l;
                c[1] = f.r_m * f.k * sigma * g / f.j_m;
                c[2] = -f.r_l * f.k * sigma * g / f.j_l;
            }
            (a, c)
        };
        let modes = if g == 0.0 {
            let (a, c) = build(0.0, true);
            vec![Mode { a, c, guards: vec![] }]
        } else {
            backlash_modes(g, 0, build)
        };
        // Start at rest with u = 0: inside the gap, or the single linear mode.
        let mode = if g == 0.0 { 0 } else { 1 };
        PiLoop {
            sys: Hybrid::new(modes, (0.25f64).min(0.5 / w)),
            mode,
            y: [0.0; 6],
            t: 0.0,
            j_m: f.j_m,
            kp,
            amp,
            w,
        }
    }

    pub fn omega_l(&self) -> f64 {
        self.y[2]
    }

    pub fn advance(&mut self, dt: f64) -> usize {
        let (t0, j_m, kp, amp, w) = (self.t, self.j_m, self.kp, self.amp, self.w);
        let forcing = move |s: f64, out: &mut Coeffs<6>| {
            for (row, r) in out.iter_mut().zip(sine_taylor(amp, w, t0 + s)) {
                row[1] = kp * r / j_m;
                row[5] = r;
            }
        };
        let mut events = Vec::new();
        self.sys
            .advance(&mut self.mode, &mut self.y, dt, &forcing, &mut events, &mut |_| {});
        self.t += dt;
        events.len()
    }
}

/// Normalised Taylor coefficients of amp sin(w (t + s)) in s: amp wⁿ sin(w t + nπ/2) / n!.
pub fn sine_taylor(amp: f64, w: f64, t: f64) -> [f64; ORDER + 1] {
    let (sn, cs) = (w * t).sin_cos();
    let mut scale = amp;
    std::array::from_fn(|n| {
        let r = match n % 4 {
            0 => sn,
            1 => cs,
            2 => -sn,
            _ => -cs,
        } * scale;
        scale *= w / (n + 1) as f64;
        r
    })
}
