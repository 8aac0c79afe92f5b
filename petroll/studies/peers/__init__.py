"""Standalone peer scripts for ``petroll bench peers`` (run with the peers' own Python; they import no
petroll)."""
