//! What the service keeps on disk, each store a directory written atomically (a locked
//! temporary file renamed into place) and read back at start-up:
//!
//! - [`recordings`]: Rerun recordings (`.rrd`) with their summaries, under a size cap;
//! - [`systems`]: users' system definitions by id, the registry that requests, the command line
//!   and the workers resolve stored ids through;
//! - [`jobs`]: jobs, their finished parts, events and results (see [`crate::jobs`]);
//! - [`entry`]: what the store says of a recording (summary, origin, owner);
//! - [`index`]: the recordings' index in memory, and where room for a new recording comes from;
//! - [`dates`]: recordings' dates as RFC 3339;
//! - [`tempfile`]: the locked temporary files both write through.

pub mod dates;
pub mod entry;
pub mod index;
pub mod jobs;
pub mod recordings;
pub mod systems;
pub mod tempfile;
