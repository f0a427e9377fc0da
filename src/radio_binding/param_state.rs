//! The parameters' values in effect ([`MissionParamState`]): the store the parameter service reads and
//! writes cfnav's [`super::param_table::PARAM_TABLE`] through.
//!
//! Job: read and write each parameter by id; check what a declaration cannot say (a goal inside the arena,
//! the start rules of `docs/mission.md`, the tuning's consistency); count accepted tuning writes
//! ([`MissionParamState::tuning_generation`]) so the endpoint hands the new tuning to the flight stack; keep
//! the persistent records. Persistent records are keyed by `group.name`
//! ([`crate::system::persistent_params::param_key`]), so they survive a table with other ids;
//! `persistent_store`/`persistent_clear` are refused while flying (the EEPROM write holds the deck bus).
//! `kalman.resetEstimation = 1` asks the endpoint to re-anchor the estimator's horizontal position at
//! `mission.startX/startY` (refused while flying), and the endpoint writes it back to 0 when done, as stock
//! clears it.
//!
//! Non-goals: no wire protocol (that is [`crate::radio::param`]), no EEPROM layout (that is
//! [`crate::system::persistent_params`]; the store only keeps the records and prepares writes).
//!
//! Memory: [`MissionParamState`] is about 2 KB (two [`super::tuning::Tuning`]s, the values in effect and
//! the power-on defaults, and the stored records' 640-byte slot image).

use crate::mission::link_loss::{LinkLossConfig, LinkLossPolicy};
use crate::mission::{MissionMode, MissionParams, StartRefusal};
use crate::nav::map::GridShape;
use crate::radio::param_decl::{ParamEntry, ParamStore, Refusal};
use crate::radio::toc::Value;
use crate::system::persistent_params::{PendingWrite, PersistentParams, param_key};
use crate::system::version;

use super::param_table::{
    ID_ARENA_X, ID_ARENA_Y, ID_CONTROLLER, ID_COVERAGE, ID_DECK_FLOW2, ID_DECK_MULTIRANGER, ID_EN_HIGH_LEVEL,
    ID_FW_MODIFIED, ID_FW_REVISION0, ID_FW_REVISION1, ID_GOAL_X, ID_GOAL_Y, ID_HEIGHT, ID_HOVER_TIME, ID_LINK_LOSS,
    ID_LINK_TIMEOUT, ID_MODE, ID_RESET_ESTIMATION, ID_SPEED, ID_START, ID_START_X, ID_START_Y, ID_WALLS, PARAM_TABLE,
};
use super::tuning::{Tuning, field_addr, tune_read, tune_write};

/// The parameters' values in effect plus what validation needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MissionParamState {
    /// `mission.start`: 1 while a mission runs (set by the radio), back to 0 when it ends (set by the firmware,
    /// which then queues a VALUE_UPDATED).
    pub start: u8,
    /// Positions, height, speed, the arena's size and walls.
    pub params: MissionParams,
    /// The drone is flying: a start is refused.
    pub flying: bool,
    /// Every deck the mission needs is present: a start is refused otherwise.
    pub decks_ok: bool,
    /// `deck.bcFlow2`: the Flow deck v2 was detected.
    pub flow2_deck: bool,
    /// `deck.bcMultiranger`: the Multi-ranger deck was detected.
    pub multiranger_deck: bool,
    /// `kalman.resetEstimation`: 1 from the write until the endpoint has reset the estimate.
    pub reset_estimation: u8,
    /// `stabilizer.controller` (0 or 1).
    pub controller: u8,
    /// `commander.enHighLevel` (0 or 1).
    pub en_high_level: u8,
    /// `mission.linkLoss` and `mission.linkTimeout` (the endpoint hands them to the navigator).
    pub link_loss: LinkLossConfig,
    /// Map capacity, cells, for [`MissionParams::validate`] at start.
    pub capacity_cells: usize,
    /// The mission parameters at power-on (the defaults cfclient shows).
    pub default_params: MissionParams,
    /// The tuning parameters in effect.
    pub tuning: Tuning,
    /// The tuning the flight stack was built with (the defaults cfclient shows).
    pub default_tuning: Tuning,
    /// Counts accepted tuning writes: the endpoint pushes [`Self::tuning`] to the stack when it changes.
    pub tuning_generation: u32,
    /// The values stored in the EEPROM (`persistent_store`).
    pub persistent: PersistentParams,
}

impl MissionParamState {
    /// Idle state with `params`, on the ground, decks present, the default tuning, nothing stored.
    pub fn new(params: MissionParams, capacity_cells: usize) -> Self {
        Self {
            start: 0,
            params,
            flying: false,
            decks_ok: true,
            flow2_deck: true,
            multiranger_deck: true,
            reset_estimation: 0,
            controller: 0,
            en_high_level: 0,
            link_loss: LinkLossConfig::DEFAULT,
            capacity_cells,
            default_params: params,
            tuning: Tuning::default(),
            default_tuning: Tuning::default(),
            tuning_generation: 0,
            persistent: PersistentParams::empty(),
        }
    }

    /// The same state with the tuning the flight stack was built with (its defaults and values in effect).
    pub fn with_tuning(mut self, tuning: Tuning) -> Self {
        self.tuning = tuning;
        self.default_tuning = tuning;
        self
    }

    /// Records which decks answered at boot (`decks_ok` is both).
    pub fn set_decks(&mut self, flow2: bool, multiranger: bool) {
        self.flow2_deck = flow2;
        self.multiranger_deck = multiranger;
        self.decks_ok = flow2 && multiranger;
    }

    /// A pending `kalman.resetEstimation` request: the caller resets the estimate, then sets the
    /// parameter back to 0 and announces it (VALUE_UPDATED). Returns the point to reset x, y to.
    pub fn pending_reset(&self) -> Option<(f32, f32)> {
        (self.reset_estimation != 0).then_some(self.params.start_m)
    }

    fn inside(&self, p: (f32, f32)) -> bool {
        let a = self.params.arena_m;
        p.0.is_finite() && p.1.is_finite() && p.0 > 0.1 && p.1 > 0.1 && p.0 < a.0 - 0.1 && p.1 < a.1 - 0.1
    }

    fn write_start(&mut self, v: u8) -> Result<(), Refusal> {
        if v == 0 {
            self.start = 0;
            return Ok(());
        }
        if self.flying {
            return Err(Refusal::StartWhileFlying);
        }
        if !self.decks_ok {
            return Err(Refusal::DeckMissing);
        }
        if self.start != 0 {
            return Err(Refusal::AlreadyRunning);
        }
        self.params.validate(self.capacity_cells).map_err(|e| match e {
            StartRefusal::AlreadyRunning => Refusal::AlreadyRunning,
            StartRefusal::BadArena => Refusal::BadArena,
            StartRefusal::OutsideArena if !self.inside(self.params.goal_m) => Refusal::GoalOutsideArena,
            StartRefusal::OutsideArena => Refusal::StartOutsideArena,
            StartRefusal::BadHeight => Refusal::BadHeight,
            StartRefusal::BadSpeed => Refusal::BadSpeed,
            StartRefusal::BadModeSetting => Refusal::OutOfRange,
        })?;
        self.start = 1;
        Ok(())
    }

    /// A float write that passed the declaration's checks.
    fn write_f32(&mut self, id: u16, v: f32) -> Result<(), Refusal> {
        let p = &self.params;
        match id {
            ID_GOAL_X | ID_GOAL_Y => {
                let goal = if id == ID_GOAL_X {
                    (v, p.goal_m.1)
                } else {
                    (p.goal_m.0, v)
                };
                if !self.inside(goal) {
                    return Err(Refusal::GoalOutsideArena);
                }
                self.params.goal_m = goal;
            }
            ID_START_X | ID_START_Y => {
                let start = if id == ID_START_X {
                    (v, p.start_m.1)
                } else {
                    (p.start_m.0, v)
                };
                if !self.inside(start) {
                    return Err(Refusal::StartOutsideArena);
                }
                self.params.start_m = start;
            }
            ID_HEIGHT => self.params.height_m = v,
            ID_SPEED => self.params.speed_m_s = v,
            // The mission modes' settings: what a running mission does cannot change under it.
            ID_HOVER_TIME | ID_COVERAGE if self.start != 0 => return Err(Refusal::AlreadyRunning),
            ID_HOVER_TIME => self.params.hover_time_s = v,
            ID_COVERAGE => self.params.coverage_target = v,
            ID_LINK_TIMEOUT => self.link_loss.timeout_s = v,
            ID_ARENA_X | ID_ARENA_Y if self.start != 0 => return Err(Refusal::AlreadyRunning),
            ID_ARENA_X | ID_ARENA_Y => {
                let arena = if id == ID_ARENA_X {
                    (v, p.arena_m.1)
                } else {
                    (p.arena_m.0, v)
                };
                if GridShape::for_arena(arena.0, arena.1, self.capacity_cells).is_none() {
                    return Err(Refusal::BadArena);
                }
                self.params.arena_m = arena;
            }
            _ => return Err(Refusal::UnknownId),
        }
        Ok(())
    }

    /// A uint8 write that passed the declaration's checks (0 or 1 for every writable uint8 here but
    /// `mission.mode` and `mission.linkLoss`, 0..2).
    fn write_u8(&mut self, id: u16, v: u8) -> Result<(), Refusal> {
        match id {
            ID_START => return self.write_start(v),
            ID_RESET_ESTIMATION if v != 0 && (self.flying || self.start != 0) => {
                return Err(Refusal::ResetWhileFlying);
            }
            ID_RESET_ESTIMATION => self.reset_estimation = v,
            ID_CONTROLLER => self.controller = v,
            ID_EN_HIGH_LEVEL => self.en_high_level = v,
            ID_MODE if self.start != 0 => return Err(Refusal::AlreadyRunning),
            ID_MODE => self.params.mode = MissionMode::from_code(v).ok_or(Refusal::OutOfRange)?,
            ID_LINK_LOSS => self.link_loss.policy = LinkLossPolicy::from_code(v).ok_or(Refusal::OutOfRange)?,
            ID_WALLS if self.start != 0 => return Err(Refusal::AlreadyRunning),
            ID_WALLS => self.params.walls = v,
            _ => return Err(Refusal::UnknownId),
        }
        Ok(())
    }
}

impl ParamStore for MissionParamState {
    const TABLE: &'static [ParamEntry] = PARAM_TABLE;

    fn read(&self, id: u16) -> Option<Value> {
        if let Some(v) = tune_read(&self.tuning, PARAM_TABLE.get(usize::from(id))?) {
            return Some(v);
        }
        let p = &self.params;
        let flag = |b: bool| Value::U8(u8::from(b));
        Some(match id {
            ID_START => Value::U8(self.start),
            ID_GOAL_X => Value::F32(p.goal_m.0),
            ID_GOAL_Y => Value::F32(p.goal_m.1),
            ID_START_X => Value::F32(p.start_m.0),
            ID_START_Y => Value::F32(p.start_m.1),
            ID_HEIGHT => Value::F32(p.height_m),
            ID_SPEED => Value::F32(p.speed_m_s),
            ID_DECK_FLOW2 => flag(self.flow2_deck),
            ID_DECK_MULTIRANGER => flag(self.multiranger_deck),
            ID_RESET_ESTIMATION => Value::U8(self.reset_estimation),
            ID_CONTROLLER => Value::U8(self.controller),
            ID_EN_HIGH_LEVEL => Value::U8(self.en_high_level),
            ID_MODE => Value::U8(p.mode.code()),
            ID_HOVER_TIME => Value::F32(p.hover_time_s),
            ID_COVERAGE => Value::F32(p.coverage_target),
            ID_LINK_LOSS => Value::U8(self.link_loss.policy.code()),
            ID_LINK_TIMEOUT => Value::F32(self.link_loss.timeout_s),
            ID_FW_REVISION0 => Value::U32(version::REVISION0),
            ID_FW_REVISION1 => Value::U16(version::REVISION1),
            ID_FW_MODIFIED => Value::U8(version::MODIFIED),
            ID_ARENA_X => Value::F32(p.arena_m.0),
            ID_ARENA_Y => Value::F32(p.arena_m.1),
            ID_WALLS => Value::U8(p.walls),
            // The other deck.* entries: decks cfnav never drives.
            _ if PARAM_TABLE.get(usize::from(id))?.group == "deck" => flag(false),
            _ => return None,
        })
    }

    fn default_value(&self, id: u16) -> Option<Value> {
        let e = PARAM_TABLE.get(usize::from(id))?;
        if let Some(v) = tune_read(&self.default_tuning, e) {
            return Some(v);
        }
        let mut power_on = Self::new(self.default_params, self.capacity_cells);
        power_on.set_decks(self.flow2_deck, self.multiranger_deck);
        power_on.read(id)
    }

    fn write(&mut self, id: u16, value: Value) -> Result<(), Refusal> {
        let e = PARAM_TABLE.get(usize::from(id)).ok_or(Refusal::UnknownId)?;
        e.check(value)?;
        if tune_read(&self.tuning, e).is_some() {
            self.tuning = tune_write(&self.tuning, e, value)?;
            self.tuning_generation = self.tuning_generation.wrapping_add(1);
            return Ok(());
        }
        match value {
            Value::U8(v) => self.write_u8(id, v),
            Value::F32(v) => self.write_f32(id, v),
            _ => Err(Refusal::WrongType),
        }
    }

    fn stored_value(&self, id: u16) -> Option<Value> {
        let e = PARAM_TABLE.get(usize::from(id)).filter(|e| e.is_persistent())?;
        let r = self.persistent.get(param_key(e.group, e.name))?;
        if r.type_code != e.ty.param_code() {
            return None;
        }
        Value::from_le(e.ty, &r.value[..e.ty.size()])
    }

    fn prepare_persistent_store(&self, id: u16) -> Result<PendingWrite, Refusal> {
        let e = PARAM_TABLE.get(usize::from(id)).ok_or(Refusal::UnknownId)?;
        if !e.is_persistent() {
            return Err(Refusal::NotPersistent);
        }
        if self.flying {
            return Err(Refusal::StoreWhileFlying);
        }
        let (bytes, _) = self.read(id).ok_or(Refusal::UnknownId)?.to_le();
        self.persistent
            .prepare_store(param_key(e.group, e.name), e.ty.param_code(), bytes)
            .map_err(|_| Refusal::StoreFull)
    }

    fn prepare_persistent_clear(&self, id: u16) -> Result<Option<PendingWrite>, Refusal> {
        let e = PARAM_TABLE.get(usize::from(id)).ok_or(Refusal::UnknownId)?;
        if !e.is_persistent() {
            return Err(Refusal::NotPersistent);
        }
        if self.flying {
            return Err(Refusal::StoreWhileFlying);
        }
        Ok(self.persistent.prepare_clear(param_key(e.group, e.name)))
    }

    fn commit_persistent(&mut self, write: PendingWrite) -> bool {
        self.persistent.commit(write)
    }

    fn set_persistent(&mut self, stored: PersistentParams) {
        self.persistent = stored;
    }

    fn aliases(&self, id: u16) -> impl Iterator<Item = u16> {
        // Two names of one field: the same address in a scratch copy of the tuning.
        let mut probe = self.tuning;
        let target = PARAM_TABLE.get(usize::from(id)).and_then(|e| field_addr(&mut probe, e));
        (0..PARAM_TABLE.len() as u16).filter(move |&other| {
            let mut probe = probe;
            other != id && target.is_some() && field_addr(&mut probe, &PARAM_TABLE[usize::from(other)]) == target
        })
    }
}
