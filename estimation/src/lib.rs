//! Yield-stress identification, online estimation and health checks (issue 5).
