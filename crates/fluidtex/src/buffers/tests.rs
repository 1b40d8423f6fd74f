use super::*;

fn dirty(len: usize, capacity: usize, seed: u32) -> Vec<u32> {
    let mut v = Vec::with_capacity(capacity);
    v.extend((0..len as u32).map(|i| i.wrapping_mul(2_654_435_761).wrapping_add(seed)));
    v
}

#[test]
fn a_reused_buffer_holds_exactly_what_a_fresh_one_would() {
    let pool = Pool::<u32>::default();
    let n = MIN_LEN + 12_345;
    // Longer than asked, filled with noise: every value must be rewritten.
    let given = dirty(n + 999, n + 999, 7);
    let address = given.as_ptr();
    pool.give(given);
    assert_eq!(pool.held(), 1);
    let v = pool.take(n, 42);
    assert_eq!(v.as_ptr(), address, "the given-back buffer is reused");
    assert_eq!(v, vec![42u32; n]);
    assert_eq!(pool.held(), 0);
    // Without a pool: the same vector.
    assert_eq!(take_from(None, n, 42u32), v);
}

#[test]
fn a_buffer_with_room_grows_to_the_length_asked() {
    let pool = Pool::<u32>::default();
    let n = MIN_LEN + 100;
    let given = dirty(MIN_LEN, n + 50, 3);
    let address = given.as_ptr();
    pool.give(given);
    let v = pool.take(n, 9);
    assert_eq!(v.as_ptr(), address);
    assert_eq!(v.len(), n);
    assert!(v.iter().all(|&x| x == 9));
}

#[test]
fn the_smallest_buffer_that_fits_is_taken_and_too_small_ones_stay() {
    let pool = Pool::<f32>::default();
    let (small, middle, large) = (MIN_LEN, 2 * MIN_LEN, 3 * MIN_LEN);
    let addresses: Vec<*const f32> = [large, small, middle]
        .into_iter()
        .map(|len| {
            let v = vec![1.5f32; len];
            let a = v.as_ptr();
            pool.give(v);
            a
        })
        .collect();
    let v = pool.take(small + 1, 0.0);
    assert_eq!(v.as_ptr(), addresses[2], "middle fits best");
    assert_eq!(pool.held(), 2);
    let w = pool.take(large, f32::NAN);
    assert_eq!(w.as_ptr(), addresses[0]);
    assert!(w.iter().all(|x| x.is_nan()));
    // Only the small one is left, and it cannot hold this:
    let z = pool.take(small + 1, 2.0);
    assert_ne!(z.as_ptr(), addresses[1]);
    assert_eq!(z, vec![2.0f32; small + 1]);
    assert_eq!(pool.held(), 1);
}

#[test]
fn small_buffers_are_dropped_and_the_pool_is_bounded() {
    let pool = Pool::<Vec2>::default();
    pool.give(vec![Vec2::ZERO; MIN_LEN - 1]);
    assert_eq!(pool.held(), 0);
    // Small requests never take a kept buffer.
    pool.give(vec![Vec2::ONE; MIN_LEN]);
    let little = pool.take(10, Vec2::X);
    assert_eq!(little, vec![Vec2::X; 10]);
    assert_eq!(pool.held(), 1);
    for _ in 0..KEEP + 3 {
        pool.give(vec![Vec2::ONE; MIN_LEN]);
    }
    assert_eq!(pool.held(), KEEP);
}

#[test]
fn buffers_of_each_type_go_to_their_own_pool() {
    let buffers = Buffers::default();
    buffers.u32.give(vec![5; MIN_LEN]);
    buffers.f32.give(vec![5.0; MIN_LEN]);
    assert_eq!(
        (buffers.u32.held(), buffers.f32.held(), buffers.vec2.held()),
        (1, 1, 0)
    );
    let v = take_from(Some(&buffers.vec2), MIN_LEN, Vec2::NAN);
    assert_eq!(v.len(), MIN_LEN);
    assert_eq!(buffers.u32.held() + buffers.f32.held(), 2);
}
