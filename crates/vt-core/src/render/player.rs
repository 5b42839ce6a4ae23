//! Eq. (6): which source frame to show, with the switch policy that postpones bad switches.

use super::RenderScene;
use crate::Result;

/// The views around a viewpoint q, as eq. (3)-(5) name them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct QSplit {
    /// `f = floor(q)`: the view at or left of q.
    pub floor: usize,
    /// `c = ceil(q)`: the view at or right of q.
    pub ceil: usize,
    /// `qbar`: the nearest view, the right one at the 0.5 tie; the moving object comes from it.
    pub nearest: usize,
}

/// `f`, `c` and `qbar` of eq. (3)-(5) for `q >= 0`.
pub fn split_q(q: f64) -> QSplit {
    let f = q.floor();
    let c = q.ceil();
    let qbar = if q - f < 0.5 { f } else { c };
    QSplit {
        floor: f as usize,
        ceil: c as usize,
        nearest: qbar as usize,
    }
}

/// What the player did to reach this frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Step {
    /// The first frame.
    Start,
    /// `j = j_prev + 1` in the same view.
    Play,
    /// `j = m + 1` after `n`: a loop wrap.
    Wrap,
    /// A view switch across `hops` views.
    Switch {
        /// Views crossed (|qbar - qbar_prev|).
        hops: usize,
    },
}

/// The source frame of one output frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameChoice {
    /// `qbar_i`.
    pub view: usize,
    /// `j_i`.
    pub frame: usize,
    /// How it was reached.
    pub step: Step,
    /// For a wrap or switch: the frame after the last one shown, in the old view (`(view,
    /// frame)`): the continuation a crossfade blends from. For a wrap only if that frame exists;
    /// for a switch always (it may lie one past the old view's last frame, when the switch left
    /// from it; a switch fade continues the old view's loop from the frame before it instead).
    pub continuation: Option<(usize, usize)>,
}

/// When the player may postpone a view switch (beyond the thesis): a switch whose seam score
/// (the eq. (2) cost of the transition from the current frame, in ordinary steps) exceeds
/// `max_seam` is postponed, and the current view keeps playing, while q stays within
/// `max_past_tie` views past the 0.5 tie and for at most `max_frames` output frames; then the
/// switch happens at the first acceptable frame, or when a bound is reached. Only one-view
/// switches are postponed (a jump across several views follows eq. (6) at once).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SwitchPolicy {
    /// Largest acceptable seam score (`f64::INFINITY`: always switch at the tie, the thesis).
    pub max_seam: f64,
    /// How far past the tie the old view may still be shown, views (at most 0.45).
    pub max_past_tie: f64,
    /// Longest postponement, output frames.
    pub max_frames: usize,
}

impl SwitchPolicy {
    /// Eq. (6) exactly: switch at the tie, whatever the seam.
    pub fn thesis() -> Self {
        Self {
            max_seam: f64::INFINITY,
            ..Self::default()
        }
    }
}

impl Default for SwitchPolicy {
    fn default() -> Self {
        Self {
            max_seam: 1.5,
            max_past_tie: 0.25,
            max_frames: 12,
        }
    }
}

/// Eq. (6) as a state machine, with counters for the render summary.
#[derive(Debug, Clone, Default)]
pub struct Player {
    state: Option<(usize, usize)>,
    /// Loop wraps so far.
    pub wraps: u64,
    /// View switches so far (a multi-view jump counts once per hop).
    pub switches: u64,
    /// When to postpone a bad switch.
    pub policy: SwitchPolicy,
    delayed: usize,
    /// Output frames shown from the old view while a bad switch was postponed.
    pub postponed_frames: u64,
}

impl Player {
    /// A player before its first frame.
    pub fn new() -> Self {
        Self::default()
    }

    /// A player with a switch policy.
    pub fn with_policy(policy: SwitchPolicy) -> Self {
        Self {
            policy,
            ..Self::default()
        }
    }

    /// Whether to postpone the switch from `(pv, pj)` to `qbar` at viewpoint q.
    fn postpone(&self, scene: &RenderScene, q: f64, pv: usize, pj: usize, qbar: usize) -> bool {
        let pol = &self.policy;
        if !pol.max_seam.is_finite() || pv.abs_diff(qbar) != 1 || self.delayed >= pol.max_frames {
            return false;
        }
        if (q - pv as f64).abs() > 0.5 + pol.max_past_tie.clamp(0.0, 0.45) {
            return false;
        }
        let v = &scene.views[pv];
        let seams = if qbar > pv {
            &v.to_next_seam
        } else {
            &v.to_prev_seam
        };
        seams.get(pj).is_some_and(|&s| s as f64 > pol.max_seam)
    }

    /// The last choice's `(view, frame)`.
    pub fn current(&self) -> Option<(usize, usize)> {
        self.state
    }

    /// Chooses the source frame for viewpoint `q` (eq. 6).
    pub fn advance(&mut self, scene: &RenderScene, q: f64) -> Result<FrameChoice> {
        scene.check_q(q)?;
        let qbar = split_q(q).nearest;
        // Switch where it matches: keep the current view a little longer if this switch is bad.
        let qbar = match self.state {
            Some((pv, pj)) if pv != qbar && self.postpone(scene, q, pv, pj, qbar) => {
                self.delayed += 1;
                self.postponed_frames += 1;
                pv
            }
            _ => {
                self.delayed = 0;
                qbar
            }
        };
        let v = &scene.views[qbar];
        let (frame, step, continuation) = match self.state {
            None => (v.loop_start + 1, Step::Start, None),
            Some((pv, pj)) if pv == qbar => {
                if pj == v.loop_end {
                    self.wraps += 1;
                    let cont = (pj + 1 < v.to_next.len()).then_some((pv, pj + 1));
                    (v.loop_start + 1, Step::Wrap, cont)
                } else {
                    (pj + 1, Step::Play, None)
                }
            }
            Some((pv, pj)) => {
                let mut s = pj;
                let mut p = pv;
                while p != qbar {
                    let (table, np) = if qbar > p {
                        (&scene.views[p].to_next, p + 1)
                    } else {
                        (&scene.views[p].to_prev, p - 1)
                    };
                    match table.get(s).copied().flatten() {
                        Some(t) => s = t,
                        None => s = scene.views[np].loop_start,
                    }
                    p = np;
                    self.switches += 1;
                }
                // Always given for a switch (the frame shown before it is `pj`), even one past the
                // old view's last frame: a blend that would show that frame drops it.
                let cont = Some((pv, pj + 1));
                (
                    s + 1,
                    Step::Switch {
                        hops: pv.abs_diff(qbar),
                    },
                    cont,
                )
            }
        };
        self.state = Some((qbar, frame));
        Ok(FrameChoice {
            view: qbar,
            frame,
            step,
            continuation,
        })
    }
}
