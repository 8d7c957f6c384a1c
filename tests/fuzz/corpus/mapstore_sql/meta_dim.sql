UPDATE meta SET value='3' WHERE key='dim';
