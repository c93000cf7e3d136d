"""One module per `dancesynth` subcommand (see apps.cli)."""
