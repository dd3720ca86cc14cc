// The closed sets of words the rig service and the dashboard server send, one frozen table each,
// used everywhere in the page; tests/dashboard/test_dashboard_words.py checks each against its
// Python home. Loaded before the other scripts.
"use strict";

// the `state` of <prefix>/status: the run engine's (orbitrig.run.states.RunState), and offline
// (orbitrig.service.protocol.OFFLINE: the service's last will)
const RunState = Object.freeze({IDLE: "idle", RUNNING: "running", PAUSED: "paused", WAITING: "waiting",
  STOPPING: "stopping", FAULTED: "faulted", OFFLINE: "offline"});

// how a run ended (orbitrig.run.states.Outcome), as the idle status's message says it
const Outcome = Object.freeze({COMPLETED: "completed", STOPPED: "stopped", ABORTED: "aborted", FAILED: "failed"});

// a run's status as the store records it (orbitrig.store.status.RunStatus): the `outcome` of the ready
// status's last_run (running: a kill left it so; unknown: a status the reader does not know)
const StoredStatus = Object.freeze({RUNNING: "running", COMPLETED: "completed", STOPPED: "stopped",
  ABORTED: "aborted", FAILED: "failed", UNKNOWN: "unknown"});

// whether what raised an alarm is still there (orbitrig.dashboard.alarms.Condition)
const Condition = Object.freeze({ACTIVE: "active", CLEARED: "cleared", UNKNOWN: "unknown"});

// why the ETA stands still, by the state that holds the run (orbitrig.run.progress.ETA_HELD): said
// after the ETA as the terminal's progress bar says it
const EtaHeld = Object.freeze({WAITING: "paused: waiting for the operator", PAUSED: "paused with the run"});

// the commands the page sends (orbitrig.run.provenance.RunCommand; the server takes those of
// orbitrig.dashboard.session.PAGE_COMMANDS)
const Command = Object.freeze({START: "start", CONFIRM: "confirm", PAUSE: "pause", RESUME: "resume", STOP: "stop",
  ABORT: "abort"});

// the session's connection to the broker (orbitrig.dashboard.feed.BrokerLink)
const BrokerLink = Object.freeze({CONNECTING: "connecting", ONLINE: "online", UNREACHABLE: "broker unreachable"});

// the words for a rig service whose status says offline while that is not known (app.js offlineUnknown: the page's
// broker link down, or the last will of a broker outage the dashboard server saw, as the server reads it): the badge's, the rig selector's, the tooltips of
// Start, Pause and Resume and the ABORT confirmation's, as the dashboard server's refusals say it
// (orbitrig.dashboard.link_lost.LINK_LOST)
const LINK_LOST = "unknown — link lost";
// the rig service whose offline is read LINK_LOST, why, and what that leaves possible, in the dashboard server's
// words (orbitrig.dashboard.link_lost: SERVICE_LINK_LOST, LOST_IN_OUTAGE, RUN_MAY_GO_ON)
const SERVICE_LINK_LOST = "the rig service's state is " + LINK_LOST;
const LOST_IN_OUTAGE = "link to the broker was lost in a broker outage";
const RUN_MAY_GO_ON = "the run may go on on the rig";

// the words of the dashboard server's refusals and outcomes the page says too, before or without asking it
// (orbitrig.dashboard.commands: SERVICE_OFFLINE, EMERGENCY_STOP, EMERGENCY, CHECK_STATE, OUTCOME_UNKNOWN, NO_BROKER)
const Refusal = Object.freeze({SERVICE_OFFLINE: "the rig service is offline", EMERGENCY_STOP: "use the rig's emergency stop",
  EMERGENCY: "if it is still running use the rig's emergency stop", CHECK_STATE: "check the rig's state",
  OUTCOME_UNKNOWN: "the outcome is unknown", NO_BROKER: "no connection to the broker: try again when it is back"});

// the `type` of a feed message (orbitrig.dashboard.feed.FeedType)
const FeedType = Object.freeze({HELLO: "hello", LINK: "link", RIGS: "rigs", RIG: "rig", STATUS: "status", ENDING: "ending",
  PROGRESS: "progress", LIVE: "live", RESULT: "result", NOTE: "note", GAP: "gap", TREND: "trend", TREND_HISTORY: "trend_history",
  ALARMS: "alarms", OUTCOMES: "outcomes", OUTCOME: "outcome", TICK: "tick", SIGNED_OUT: "signed_out"});

// what a status's message says (orbitrig.dashboard.alarms): what an interlock's suspension begins with, what
// a waiting or suspended status says after its own words while a pause asked meanwhile is pending, and what a
// closing status's grouped warnings each begin with (orbitrig.service.protocol.GROUPED_WARNING)
const StatusSaid = Object.freeze({SUSPENDED: "suspended by interlock:", PAUSE_REQUESTED: "; pause requested",
  GROUPED_WARNING: "; warning: "});
