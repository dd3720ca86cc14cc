"""The help of the rig configuration option every command shares (``--config``; acquire's
``--rig``): where the configuration is found without it, in the order of orbitrig.config.home
(README "Where commands find the configuration")."""

RIG_CONFIG_HELP = (
    "rig configuration TOML (default: rig.toml in $ORBITRIG_HOME, else in the current directory, "
    "else the shipped one; `orbitrig init DIR` writes one to edit)"
)
