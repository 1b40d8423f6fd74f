//! The rulings that judge a run against the floor run (advect) on the same
//! frames ([`judge_against_floor_on`]), on runs made up frame by frame: a
//! rule that passes a good run must fail its known-bad twin.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use super::*;
use crate::metrics::Verdict;

/// One made-up frame: the per-frame numbers the rulings read.
#[derive(Clone, Copy)]
struct F {
    switch: f64,
    popping: f64,
    follow: f64,
    epe: f64,
    /// Unforced switch share (NaN: the method records no causes).
    unforced: f64,
    /// The per-frame renewal floor (advect's growth of its
    /// holder-past-δ_max share).
    new_floor: f64,
}

const CALM: F = F {
    switch: 0.04,
    popping: 0.01,
    follow: 0.2,
    epe: 0.1,
    unforced: 0.0,
    new_floor: 0.0,
};

/// A run of `name` over frames `0..n`, frame k given by `frame(k)`.
fn made_up(name: &str, n: i32, frame: impl Fn(i32) -> F) -> MethodRun {
    let thresholds = Thresholds::committed().unwrap();
    let frames: Vec<FrameRecord> = (0..n)
        .map(|k| {
            let f = frame(k);
            let mut values = [f64::NAN; 10];
            for (m, v) in [
                (Metric::SourceSwitch, f.switch),
                (Metric::Popping, f.popping),
                (Metric::ColourFollow, f.follow),
                (Metric::FlowEpe, f.epe),
            ] {
                values[PER_FRAME.iter().position(|&p| p == m).unwrap()] = v;
            }
            FrameRecord {
                frame: k,
                seconds: 0.0,
                patches: None,
                values,
                still: false,
                anisotropy: f64::NAN,
                point_sources: Vec::new(),
                switch_same_points: [f64::NAN; 2],
                switch_causes: CauseShares {
                    unforced: f.unforced,
                    holder_distorted_new: f.new_floor,
                    holder_distorted: 0.0,
                    ..CauseShares::NONE
                },
                state_agreement: f64::NAN,
                state_agreement_decisive: f64::NAN,
            }
        })
        .collect();
    let summaries = Metric::ALL
        .iter()
        .map(|&m| {
            let values: Vec<f64> = frames.iter().map(|r| r.value(m)).collect();
            thresholds.summarize(m, &values)
        })
        .collect();
    MethodRun {
        method: name.into(),
        frames,
        summaries,
        notes: Vec::new(),
        renders: Vec::new(),
        fidelity_scale: f64::NAN,
        blends: false,
    }
}

/// Turns a good frame `k` into its known-bad twin.
type Spoil = fn(i32, F) -> F;

fn verdict(r: &MethodRun, m: Metric) -> Verdict {
    r.summary(m).unwrap().verdict
}

fn judged(mut runs: Vec<MethodRun>) -> Vec<MethodRun> {
    judge_against_floor_on(&mut runs, &Thresholds::committed().unwrap(), "");
    runs
}

#[test]
fn the_per_frame_renewal_floor_is_the_growth_of_the_cumulative_one() {
    assert_eq!(renewal_floor_growth(0.25, 0.375), 0.125);
    // Patches relaxing under δ_max make no room for others.
    assert_eq!(renewal_floor_growth(0.5, 0.25), 0.0);
    assert!(renewal_floor_growth(f64::NAN, 0.25).is_nan());
    assert!(renewal_floor_growth(0.25, f64::NAN).is_nan());
    let c = crate::metrics::SwitchCauses {
        covered: 8,
        forced: 4,
        forced_eroding: 2,
        unforced: 3,
        unforced_shown: 1,
        unforced_on_top: 1,
        distorted: 2,
    };
    let s = CauseShares::of(&c, 0.125);
    assert_eq!(
        [s.forced, s.forced_eroding, s.unforced, s.unforced_border],
        [0.5, 0.25, 0.375, 0.125]
    );
    assert_eq!([s.unforced_on_top, s.unforced_other], [0.125, 0.125]);
    assert_eq!([s.holder_distorted, s.holder_distorted_new], [0.25, 0.125]);
}

#[test]
fn unforced_switches_are_judged_against_advect_after_the_first_lifetime() {
    // 30 frames: the first lifetime is frames 0-11.
    let advect = || made_up("advect", 30, |_| CALM);
    // Erosion renews a quarter of the surface per frame, all forced but 5
    // points: within 2 points of advect's 4 % on every frame.
    let renewing = |k: i32| F {
        switch: 0.25,
        unforced: if k == 5 { 0.3 } else { 0.05 },
        ..CALM
    };
    let runs = judged(vec![made_up("erosion", 30, renewing), advect()]);
    assert_eq!(verdict(&runs[0], Metric::SourceSwitch), Verdict::Pass);
    assert!(
        runs[0]
            .notes
            .iter()
            .any(|n| n.contains("on unforced switches") && n.contains("from 12 on")),
        "{:?}",
        runs[0].notes
    );
    // The known-bad twin: 7 % unforced on one frame after the first
    // lifetime, 3 points above advect.
    let over = |k: i32| F {
        unforced: if k == 20 { 0.07 } else { 0.05 },
        ..renewing(k)
    };
    let runs = judged(vec![made_up("erosion", 30, over), advect()]);
    assert_eq!(verdict(&runs[0], Metric::SourceSwitch), Verdict::Fail);
    // A run that records no causes is judged on its whole share: the same
    // quarter fails.
    let blind = |k: i32| F {
        unforced: f64::NAN,
        ..renewing(k)
    };
    let runs = judged(vec![made_up("other", 30, blind), advect()]);
    assert_eq!(verdict(&runs[0], Metric::SourceSwitch), Verdict::Fail);
    // A short run is judged on every frame: frame 5's 30 % fails it.
    let runs = judged(vec![
        made_up("erosion", 12, renewing),
        made_up("advect", 12, |_| CALM),
    ]);
    assert_eq!(verdict(&runs[0], Metric::SourceSwitch), Verdict::Fail);
}

#[test]
fn a_method_that_blends_has_its_switch_share_as_information() {
    let boiling = |_| F {
        switch: 0.5,
        unforced: f64::NAN,
        ..CALM
    };
    let mut layered = made_up("lapped-rigid", 30, boiling);
    layered.blends = true;
    let runs = judged(vec![
        layered,
        made_up("lapped-rigid", 30, boiling),
        made_up("advect", 30, |_| CALM),
    ]);
    assert_eq!(verdict(&runs[0], Metric::SourceSwitch), Verdict::NoData);
    assert!(runs[0].notes.iter().any(|n| n.contains("blends layers")));
    // The same shares from a method that shows one source per texel fail.
    assert_eq!(verdict(&runs[1], Metric::SourceSwitch), Verdict::Fail);
}

#[test]
fn violent_frames_judge_popping_against_advect_and_leave_switches_out() {
    // Frames 3-5 and 20 are violent: advect's per-frame renewal floor is
    // 8 % there, exactly 5 % (not above the bar) on frame 6.
    let floor = |k: i32| match k {
        3..=5 | 20 => 0.08,
        6 => 0.05,
        _ => 0.0,
    };
    let advect = || {
        made_up("advect", 30, |k| F {
            popping: if floor(k) > 0.0 { 0.05 } else { 0.01 },
            new_floor: floor(k),
            ..CALM
        })
    };
    // Erosion pops 7 % on violent frames (2 points above advect), 1 %
    // elsewhere, and switches a third of its points on frame 20.
    let erosion = |k: i32| F {
        popping: if floor(k) > 0.05 { 0.07 } else { 0.01 },
        unforced: if k == 20 { 0.3 } else { 0.0 },
        follow: if k == 4 { 0.9 } else { 0.2 },
        ..CALM
    };
    let runs = judged(vec![made_up("erosion", 30, erosion), advect()]);
    let e = &runs[0];
    assert_eq!(verdict(e, Metric::Popping), Verdict::Pass);
    assert_eq!(verdict(e, Metric::SourceSwitch), Verdict::Pass);
    // Frame 4's colour follow lies in the first lifetime of a violent
    // frame: information.
    assert_eq!(verdict(e, Metric::ColourFollow), Verdict::Pass);
    assert!(
        e.notes
            .iter()
            .any(|n| n.contains("4 violent frame(s) (3–5, 20)")),
        "{:?}",
        e.notes
    );
    // Known-bad twins: 3 points above advect on a violent frame; 6 % on
    // the calm frame 6 (the absolute worst 5 % holds there); a colour
    // follow of 0.9 on the violent frame 20 or on a calm frame.
    let cases: [(&str, Metric, Spoil); 4] = [
        ("violent popping", Metric::Popping, |k, f| F {
            popping: if k == 4 { 0.08 } else { f.popping },
            ..f
        }),
        ("calm popping", Metric::Popping, |k, f| F {
            popping: if k == 6 { 0.06 } else { f.popping },
            ..f
        }),
        ("violent follow", Metric::ColourFollow, |k, f| F {
            follow: if k == 20 { 0.9 } else { f.follow },
            ..f
        }),
        ("calm follow", Metric::ColourFollow, |k, f| F {
            follow: if k == 8 { 0.9 } else { f.follow },
            ..f
        }),
    ];
    for (what, metric, bad) in cases {
        let runs = judged(vec![
            made_up("erosion", 30, |k| bad(k, erosion(k))),
            advect(),
        ]);
        assert_eq!(verdict(&runs[0], metric), Verdict::Fail, "{what}");
    }
    // Without violent frames the absolute popping rule stands: 7 % fails.
    let calm_advect = made_up("advect", 30, |_| CALM);
    let runs = judged(vec![made_up("erosion", 30, erosion), calm_advect]);
    assert_eq!(verdict(&runs[0], Metric::Popping), Verdict::Fail);
}

#[test]
fn the_end_point_error_is_judged_against_advect_where_advect_misses_it() {
    let with_epe = |name: &str, epe: f64| made_up(name, 12, |_| F { epe, ..CALM });
    // advect at 0.4 px misses 0.25: 0.5 passes, 0.52 does not.
    let runs = judged(vec![
        with_epe("erosion", 0.5),
        with_epe("advect", 0.4),
        with_epe("blend", 0.52),
    ]);
    assert_eq!(verdict(&runs[0], Metric::FlowEpe), Verdict::Pass);
    assert_eq!(verdict(&runs[1], Metric::FlowEpe), Verdict::Pass);
    assert_eq!(verdict(&runs[2], Metric::FlowEpe), Verdict::Fail);
    assert!(
        runs[0]
            .notes
            .iter()
            .any(|n| n.contains("advect's 0.400 px"))
    );
    // Where advect passes, the absolute rule: 0.3 fails.
    let runs = judged(vec![with_epe("erosion", 0.3), with_epe("advect", 0.2)]);
    assert_eq!(verdict(&runs[0], Metric::FlowEpe), Verdict::Fail);
}
