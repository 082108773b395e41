"""Python SDK for the SpaceMesh service."""
