"""The scripts ``petroll bench peers`` runs, one per solver (``solve_<name>.py``), each in a fresh process:
petroll's with petroll's Python, the peers' with their own (.venv-peers; those import no petroll)."""
