"""`ncbot robot serve`: people play the simulated robot in a browser (one SAPIEN scene and MCAP log per tab)."""
from ncbot.pipelines.serve.session import ServeConfig, Session, SessionError

__all__ = ["ServeConfig", "Session", "SessionError"]
