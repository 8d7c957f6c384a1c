UPDATE meta SET value='1' WHERE key='next_id'; UPDATE layout SET mu='abcd';
