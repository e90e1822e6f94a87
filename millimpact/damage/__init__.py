"""The liner's damage map: a mill's impact spectrum binned by place, speed and angle, each bin's
response from the table engine and the repeated-impact response, combined per revolution (DESIGN.md 12)."""
