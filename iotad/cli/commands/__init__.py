"""One module per `iotad` subcommand; each defines `register(subparsers)` and optionally ORDER."""
