"""The system: what a system file declares (the declaration, the one reader of its TOML), and
the checked model of it that every other part of the launcher takes."""
