//! The in-memory index of the recordings store: entries in insertion order, bytes in all and
//! per owner, and where room for a new recording comes from ([`Index::make_room`]): its owner's
//! own oldest recordings past the owner's quota or the store's cap, then, past the cap, those
//! without an owner — never another owner's.

use std::collections::BTreeMap;

use super::recordings::{RecordingEntry, RecordingOwner, StoreError};

/// The entries, with bytes in all and per owner.
#[derive(Debug, Default)]
pub struct Index {
    /// Entries with their insertion order (which breaks ties in creation time).
    pub(super) entries: BTreeMap<String, (u64, RecordingEntry)>,
    next_seq: u64,
    pub(super) total: u64,
    /// Bytes per owner (recordings without an owner under "").
    by_owner: BTreeMap<String, u64>,
}

impl Index {
    /// Adds an entry.
    pub fn insert(&mut self, entry: RecordingEntry) {
        self.total += entry.bytes;
        *self.by_owner.entry(owner_key(&entry)).or_default() += entry.bytes;
        self.next_seq += 1;
        self.entries
            .insert(entry.id.clone(), (self.next_seq, entry));
    }

    /// Removes an entry.
    pub fn remove(&mut self, id: &str) -> Option<RecordingEntry> {
        let (_, entry) = self.entries.remove(id)?;
        self.total -= entry.bytes;
        let key = owner_key(&entry);
        if let Some(bytes) = self.by_owner.get_mut(&key) {
            *bytes -= entry.bytes;
            if *bytes == 0 {
                self.by_owner.remove(&key);
            }
        }
        Some(entry)
    }

    /// Bytes of every recording.
    pub fn total(&self) -> u64 {
        self.total
    }

    /// Bytes of `owner`'s recordings.
    pub fn owned(&self, owner: &str) -> u64 {
        self.by_owner.get(owner).copied().unwrap_or(0)
    }

    /// The id of the oldest entry other than `keep` owned by `owner` ("" for no owner; any
    /// owner for `None`).
    pub(super) fn oldest_except(&self, keep: &str, owner: Option<&str>) -> Option<String> {
        self.entries
            .iter()
            .filter(|(id, (_, e))| id.as_str() != keep && owner.is_none_or(|o| owner_key(e) == o))
            .min_by_key(|(_, (seq, e))| (e.created_unix_ms, *seq))
            .map(|(id, _)| id.clone())
    }

    /// Makes room for the new recording `keep` of `owner`: removes the owner's oldest other
    /// recordings while the owner is past its quota or the store past its cap, and past the cap
    /// then the oldest recordings without an owner; never another owner's. Returns those
    /// removed, or [`StoreError::FullOfOthers`] (removing nothing) when that is not enough.
    pub fn make_room(
        &mut self,
        keep: &str,
        owner: &RecordingOwner,
        max_bytes: u64,
    ) -> Result<Vec<RecordingEntry>, StoreError> {
        let index = self;
        // Plan first, so that a refusal removes nothing.
        let mut plan: Vec<String> = Vec::new();
        let mut owned = index.owned(&owner.name);
        let mut total = index.total;
        let mut candidates = index
            .entries
            .iter()
            .filter(|(id, (_, e))| {
                id.as_str() != keep && e.owner.as_deref().is_none_or(|o| o == owner.name)
            })
            .map(|(id, (seq, e))| {
                (
                    e.owner.is_some(),
                    e.created_unix_ms,
                    *seq,
                    id.clone(),
                    e.bytes,
                )
            })
            .collect::<Vec<_>>();
        // The owner's own first (oldest first), then those without an owner.
        candidates.sort_by(|a, b| (!a.0, a.1, a.2).cmp(&(!b.0, b.1, b.2)));
        for (own, _, _, id, bytes) in candidates {
            let past_quota = owner.quota.is_some_and(|q| owned > q);
            if !past_quota && total <= max_bytes {
                break;
            }
            if !own && total <= max_bytes {
                continue;
            }
            plan.push(id);
            total -= bytes;
            if own {
                owned -= bytes;
            }
        }
        if total > max_bytes || owner.quota.is_some_and(|q| owned > q) {
            let bytes = index.entries.get(keep).map_or(0, |(_, e)| e.bytes);
            return Err(StoreError::FullOfOthers {
                bytes,
                max: max_bytes,
            });
        }
        Ok(plan.iter().filter_map(|id| index.remove(id)).collect())
    }
}

/// The key of an entry's owner in the index ("" for none).
fn owner_key(entry: &RecordingEntry) -> String {
    entry.owner.clone().unwrap_or_default()
}
