//! What a key asks the demo to do: change the scene, or change what the app
//! shows around it (help, statistics), pause or quit. The scene never sees the
//! app's commands, so it has nothing to ignore.

pub use crate::scene::{Axis, LightTurn, SceneCommand, Sense};

/// One key's worth of intent, as the key-to-command map gives it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Command {
    /// A change to the scene; R ([`SceneCommand::Reset`]) also clears the
    /// help and statistics, since the starting scene has neither.
    Scene(SceneCommand),
    /// Show or hide the on-screen help.
    ToggleHelp,
    /// Show or hide the statistics lines.
    ToggleStats,
    /// Any key that is not a command: wait for the next key, as Abrash's
    /// original program does.
    Pause,
    /// Leave the demo.
    Quit,
    /// Show or leave the report screen (`crate::report`): while it is up,
    /// the arrows and Page Up/Down scroll its log, R leaves it for the
    /// starting scene, Esc quits, and other keys do nothing.
    ToggleReport,
}

impl From<SceneCommand> for Command {
    fn from(command: SceneCommand) -> Self {
        Command::Scene(command)
    }
}
