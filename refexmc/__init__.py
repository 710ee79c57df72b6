"""refexmc: fast, reproducible Monte-Carlo campaigns for thruster-controlled attitude control."""

__version__ = "0.1.0"


def flight_code_digest(numba_version):
    """sha256 (16 hex digits) of what flies a run: ``refexmc/_jit.py``, ``refexmc/core/*.py`` and
    the numba version given. It names the kernel cache's directory (``_jit.cache_dir``) and an
    output's flight code (``campaign.storage.flight_code``: ``--resume`` refuses other code)."""
    import hashlib
    from pathlib import Path

    package = Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted([package / "_jit.py", *(package / "core").glob("*.py")]):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    digest.update(numba_version.encode())
    return digest.hexdigest()[:16]
