//! # slam-io: datasets in, maps and metrics out
//!
//! Will hold readers (Freiburg course data, CARMEN logs, UTIAS MRCLAM, relations files, TUM
//! trajectories), writers (TUM, ROS map_server, landmarks CSV, metrics JSON, PNG pictures)
//! and the accuracy metrics (ATE, RPE, Kümmerle relations, landmark error, NEES/NIS).
