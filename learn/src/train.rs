//! Training driver.
