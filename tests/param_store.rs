//! The parameter record in two pages against a flash that loses power at every step of a store:
//! after the cut the board boots on the last committed settings (never on defaults once there
//! were settings), on the new ones only if the commit landed, and the next store works.

use core::future::Future;
use core::pin::pin;
use core::task::{Context, Poll, Waker};
use piezo_drive::controller::ControllerConfig;
use piezo_drive::defaults::controller_config;
use piezo_drive::param_store::{
    self, FlashFault, Page, PageState, ParamPages, StoreError, RECORD_SPAN, USED_LEN, WRITE_SIZE,
};
use piezo_drive::storage::{self, StorageError};

/// How a double word that was being written when the power went reads afterwards.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Tear {
    /// The flash's ECC flags it: a read of it fails.
    Ecc,
    /// Some of its bits programmed (flash bits only go from 1 to 0), no ECC error.
    HalfBits,
}

/// Two pages of flash that fail from operation `cut_after` on (an erase is one operation, each
/// programmed double word one): the operation at the cut is left torn, the later ones never
/// happen.
struct TearingFlash {
    pages: [[u8; USED_LEN]; 2],
    ecc: [[bool; USED_LEN / WRITE_SIZE]; 2],
    cut_after: usize,
    ops: usize,
    tear: Tear,
}

fn index(page: Page) -> usize {
    match page {
        Page::A => 0,
        Page::B => 1,
    }
}

impl TearingFlash {
    fn erased() -> Self {
        TearingFlash {
            pages: [[0xFF; USED_LEN]; 2],
            ecc: [[false; USED_LEN / WRITE_SIZE]; 2],
            cut_after: usize::MAX,
            ops: 0,
            tear: Tear::Ecc,
        }
    }

    /// Counts one operation; false once the power is gone (the one at the cut is reported so
    /// the caller can tear it).
    fn power(&mut self) -> Option<bool> {
        let n = self.ops;
        self.ops += 1;
        match n.cmp(&self.cut_after) {
            std::cmp::Ordering::Less => Some(true),
            std::cmp::Ordering::Equal => Some(false),
            std::cmp::Ordering::Greater => None,
        }
    }

    /// The power comes back: everything works again.
    fn reboot(&mut self) {
        self.cut_after = usize::MAX;
        self.ops = 0;
    }
}

impl ParamPages for TearingFlash {
    fn read(&mut self, page: Page, buf: &mut [u8]) -> Result<(), FlashFault> {
        let p = index(page);
        if self.ecc[p].iter().take(buf.len().div_ceil(WRITE_SIZE)).any(|e| *e) {
            return Err(FlashFault::Ecc);
        }
        buf.copy_from_slice(&self.pages[p][..buf.len()]);
        Ok(())
    }

    async fn erase(&mut self, page: Page) -> Result<(), FlashFault> {
        let p = index(page);
        match self.power() {
            Some(true) => {
                self.pages[p] = [0xFF; USED_LEN];
                self.ecc[p] = [false; USED_LEN / WRITE_SIZE];
                Ok(())
            }
            Some(false) => {
                // Cut mid-erase: the first half of the words erased, one torn, the rest as before.
                let words = USED_LEN / WRITE_SIZE;
                for w in 0..words / 2 {
                    self.pages[p][w * WRITE_SIZE..(w + 1) * WRITE_SIZE].fill(0xFF);
                    self.ecc[p][w] = false;
                }
                self.tear_word(p, words / 2, &[0xFF; WRITE_SIZE]);
                Err(FlashFault::Failed)
            }
            None => Err(FlashFault::Failed),
        }
    }

    async fn program(&mut self, page: Page, offset: usize, data: &[u8]) -> Result<(), FlashFault> {
        assert_eq!(offset % WRITE_SIZE, 0, "programs whole double words");
        assert_eq!(data.len() % WRITE_SIZE, 0, "programs whole double words");
        let p = index(page);
        for (k, word) in data.chunks_exact(WRITE_SIZE).enumerate() {
            let w = offset / WRITE_SIZE + k;
            let at = w * WRITE_SIZE;
            assert!(
                self.pages[p][at..at + WRITE_SIZE].iter().all(|b| *b == 0xFF) && !self.ecc[p][w],
                "programs only erased flash ({page:?} word {w})"
            );
            match self.power() {
                Some(true) => self.pages[p][at..at + WRITE_SIZE].copy_from_slice(word),
                Some(false) => {
                    self.tear_word(p, w, word);
                    return Err(FlashFault::Failed);
                }
                None => return Err(FlashFault::Failed),
            }
        }
        Ok(())
    }
}

impl TearingFlash {
    fn tear_word(&mut self, p: usize, w: usize, target: &[u8]) {
        let at = w * WRITE_SIZE;
        match self.tear {
            Tear::Ecc => self.ecc[p][w] = true,
            Tear::HalfBits => {
                // The first half of the word reached its target, the second half is as it was
                // ANDed with half the target's bits (a program only clears bits).
                for (i, (b, t)) in self.pages[p][at..at + WRITE_SIZE].iter_mut().zip(target).enumerate() {
                    *b = if i < WRITE_SIZE / 2 { *t } else { *b & (*t | 0x0F) };
                }
            }
        }
    }
}

/// Runs a future whose every await is ready at once (the flash above never waits).
fn run<F: Future>(f: F) -> F::Output {
    let mut f = pin!(f);
    let mut cx = Context::from_waker(Waker::noop());
    loop {
        if let Poll::Ready(out) = f.as_mut().poll(&mut cx) {
            return out;
        }
    }
}

/// Settings that differ from the defaults and from each other by `n`.
fn settings(n: u32) -> ControllerConfig {
    let mut c = controller_config();
    c.kp_per_s = 40.0 + n as f32;
    c.travel_max_nm = 5_000_000 + n as i64;
    c
}

/// The flash as single-page firmware left it: its record at the start of page B, no commit word.
fn legacy(cfg: &ControllerConfig) -> TearingFlash {
    let mut f = TearingFlash::erased();
    let record = storage::encode(cfg);
    f.pages[1][..record.len()].copy_from_slice(&record);
    f
}

fn boot(flash: &mut TearingFlash) -> (ControllerConfig, Result<Page, StorageError>) {
    flash.reboot();
    let (cfg, _, page) = param_store::load(flash, &controller_config());
    (cfg, page)
}

/// Starting flashes with settings `old` committed: in page A, in page B after two stores, and
/// as single-page firmware left them.
fn starts(old: &ControllerConfig) -> Vec<(&'static str, TearingFlash)> {
    let d = controller_config();
    let mut in_a = TearingFlash::erased();
    run(param_store::store(&mut in_a, old, &d)).expect("store on fresh flash");
    let mut in_b = TearingFlash::erased();
    run(param_store::store(&mut in_b, &settings(99), &d)).expect("first store");
    run(param_store::store(&mut in_b, old, &d)).expect("second store");
    vec![("page A current", in_a), ("page B current", in_b), ("single-page record", legacy(old))]
}

#[test]
fn stores_alternate_pages_and_the_newest_loads() {
    let d = controller_config();
    let mut f = TearingFlash::erased();
    assert_eq!(boot(&mut f), (d, Err(StorageError::NoRecord)));
    let mut pages = Vec::new();
    for n in 1..=5 {
        pages.push(run(param_store::store(&mut f, &settings(n), &d)).expect("store"));
        assert_eq!(boot(&mut f), (settings(n), Ok(*pages.last().expect("one"))));
    }
    assert_eq!(pages, [Page::A, Page::B, Page::A, Page::B, Page::A]);
}

#[test]
fn a_record_from_single_page_firmware_loads_and_survives_the_first_store() {
    let d = controller_config();
    let mut f = legacy(&settings(1));
    assert_eq!(boot(&mut f), (settings(1), Ok(Page::B)));
    // The first store goes to page A and leaves the old record where it was.
    assert_eq!(run(param_store::store(&mut f, &settings(2), &d)), Ok(Page::A));
    assert_eq!(boot(&mut f), (settings(2), Ok(Page::A)));
    assert_eq!(run(param_store::store(&mut f, &settings(3), &d)), Ok(Page::B));
    assert_eq!(boot(&mut f), (settings(3), Ok(Page::B)));
}

#[test]
fn a_power_cut_at_any_step_of_a_store_keeps_the_last_good_record() {
    let d = controller_config();
    let (old, new, after) = (settings(1), settings(2), settings(3));
    // Operations of one store: the erase, the record's double words, the commit word.
    let store_ops = 1 + RECORD_SPAN / WRITE_SIZE + 1;
    let mut cases = 0;
    for tear in [Tear::Ecc, Tear::HalfBits] {
        for cut in 0..store_ops {
            for (start, mut f) in starts(&old) {
                f.tear = tear;
                f.reboot();
                f.cut_after = cut;
                let stored = run(param_store::store(&mut f, &new, &d));
                assert!(stored.is_err(), "{start}, cut at {cut}: the store cannot finish without power");
                let (cfg, page) = boot(&mut f);
                // Only the commit word (the last operation) makes the new record current; with
                // it torn the old one stays.
                assert_eq!(cfg, old, "{start}, cut at operation {cut} of {store_ops} ({tear:?})");
                assert!(page.is_ok(), "{start}, cut at {cut}: a record loads");
                // The board then stores again, and that store holds.
                let again = run(param_store::store(&mut f, &after, &d));
                assert!(again.is_ok(), "{start}, cut at {cut}: the next store fails: {again:?}");
                assert_eq!(boot(&mut f).0, after, "{start}, cut at {cut}: the next store loads");
                cases += 1;
            }
        }
    }
    assert_eq!(cases, 2 * store_ops * 3);
}

#[test]
fn a_cut_after_the_commit_loads_the_new_record() {
    let d = controller_config();
    let store_ops = 1 + RECORD_SPAN / WRITE_SIZE + 1;
    for (start, mut f) in starts(&settings(1)) {
        f.reboot();
        f.cut_after = store_ops; // the first operation after the store
        assert_eq!(run(param_store::store(&mut f, &settings(2), &d)).map(|_| ()), Ok(()), "{start}");
        assert_eq!(boot(&mut f).0, settings(2), "{start}");
    }
}

#[test]
fn a_page_that_reads_damaged_is_never_the_current_one() {
    let d = controller_config();
    let mut f = TearingFlash::erased();
    run(param_store::store(&mut f, &settings(1), &d)).expect("store");
    run(param_store::store(&mut f, &settings(2), &d)).expect("store");
    // Page B (current, seq 2) gets a flipped record byte under an intact commit word.
    f.pages[1][12] ^= 0x10;
    let (cfg, states, page) = param_store::load(&mut f, &d);
    assert_eq!((cfg, page), (settings(1), Ok(Page::A)));
    assert_eq!(states[1], PageState::Damaged);
    // An out-of-range setting is refused before the flash is touched.
    let mut bad = settings(3);
    bad.kp_per_s = f32::NAN;
    let ops = f.ops;
    assert_eq!(run(param_store::store(&mut f, &bad, &d)), Err(StoreError::OutOfRange));
    assert_eq!(f.ops, ops);
}
