//! Encoding a recording into `.rrd` bytes: a log sink that hands messages to an encoder on its
//! own thread, so that encoding overlaps with building the next columns.

use std::io::Write;
use std::sync::mpsc;
use std::time::Duration;

use rerun::external::re_log_encoding::{CrateVersion, Encoder, EncodingOptions};
use rerun::external::re_log_types::LogMsg;
use rerun::sink::{LogSink, SinkFlushError};
use rerun::{RecordingStream, RecordingStreamBuilder};

use super::{RecordingError, APPLICATION_ID};

/// A sink that encodes messages into `.rrd` form on its own thread as they come, so that
/// encoding overlaps with building the next columns. The encoder's result (the writer, or the
/// first error) comes back through the thread's join handle once the sink is dropped.
pub(super) struct EncodingSink {
    tx: mpsc::SyncSender<SinkCommand>,
}

enum SinkCommand {
    Message(Box<LogMsg>),
    Flush(mpsc::Sender<Result<(), String>>),
}

/// The encoder thread of an [`EncodingSink`].
pub(super) type EncoderThread<W> = std::thread::JoinHandle<Result<W, RecordingError>>;

/// The result of an encoder thread: the writer once the `.rrd` stream is complete.
pub(super) fn join<W>(thread: EncoderThread<W>) -> Result<W, RecordingError> {
    thread
        .join()
        .unwrap_or_else(|_| Err(RecordingError::Sink("the encoder panicked".into())))
}

impl EncodingSink {
    /// Starts an encoder writing to `writer`; it finishes the stream when the sink is dropped.
    pub(super) fn spawn<W: Write + Send + 'static>(
        writer: W,
    ) -> Result<(Self, EncoderThread<W>), RecordingError> {
        let mut encoder = Encoder::new_eager(
            CrateVersion::LOCAL,
            EncodingOptions::PROTOBUF_COMPRESSED,
            writer,
        )?;
        let (tx, rx) = mpsc::sync_channel::<SinkCommand>(64);
        let thread = std::thread::Builder::new()
            .name("rrd-encoder".into())
            .spawn(move || {
                let mut failure: Option<RecordingError> = None;
                while let Ok(command) = rx.recv() {
                    match command {
                        SinkCommand::Message(msg) => {
                            if failure.is_none() {
                                if let Err(e) = encoder.append(&msg) {
                                    failure = Some(e.into());
                                }
                            }
                        }
                        SinkCommand::Flush(done) => {
                            let _ = done.send(match &failure {
                                Some(e) => Err(e.to_string()),
                                None => Ok(()),
                            });
                        }
                    }
                }
                if let Some(e) = failure {
                    return Err(e);
                }
                encoder.finish()?;
                Ok(encoder.into_inner()?)
            })
            .map_err(|e| RecordingError::Sink(format!("cannot start the encoder: {e}")))?;
        Ok((EncodingSink { tx }, thread))
    }
}

impl LogSink for EncodingSink {
    fn send(&self, msg: LogMsg) {
        // A closed channel means the encoder failed; the failure is reported at the end.
        let _ = self.tx.send(SinkCommand::Message(Box::new(msg)));
    }

    fn flush_blocking(&self, timeout: Duration) -> Result<(), SinkFlushError> {
        let (done, wait) = mpsc::channel();
        let failed = |message: String| SinkFlushError::Failed { message };
        self.tx
            .send(SinkCommand::Flush(done))
            .map_err(|_| failed("the encoder stopped".into()))?;
        match wait.recv_timeout(timeout) {
            Ok(result) => result.map_err(failed),
            Err(mpsc::RecvTimeoutError::Timeout) => Err(SinkFlushError::Timeout),
            Err(mpsc::RecvTimeoutError::Disconnected) => Err(failed("the encoder stopped".into())),
        }
    }
}

/// Writes a recording named `name` to `writer` in `.rrd` form: `log` logs everything into the
/// stream, then the stream is flushed and the encoder finished (footer included). Returns the
/// writer.
pub(super) fn write<W: Write + Send + 'static>(
    writer: W,
    name: String,
    log: impl FnOnce(&RecordingStream) -> Result<(), RecordingError>,
) -> Result<W, RecordingError> {
    // Enabled whatever the `RERUN` environment variable says.
    let rec = RecordingStreamBuilder::new(APPLICATION_ID)
        .enabled(true)
        .recording_name(name)
        .buffered()?;
    let (sink, thread) = EncodingSink::spawn(writer)?;
    rec.set_sink(Box::new(sink));
    let logged = log(&rec);
    let flushed = rec
        .flush_blocking()
        .map_err(|e| RecordingError::Sink(e.to_string()));
    // Dropping the last handle of the stream drops the sink, which ends the encoder.
    drop(rec);
    let written = join(thread);
    logged?;
    // The encoder's own error carries its cause (a full disk, say); the flush reports it only
    // as text, so it goes first.
    let writer = written?;
    flushed?;
    Ok(writer)
}
